"""Writing ``ltc-recording/1`` folders (DESIGN §3): recording.yaml, poses.txt, rgb/, depth/,
annotations/, detections/ and ground_truth.json. ``ltc simulate`` and the tests write through this
one module, so every recording ltc makes has the same layout and formatting.

Everything written is deterministic (PNG through zlib, JSON and YAML with a fixed key order), so a
writer fed the same arrays writes byte-identical files.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import yaml
from PIL import Image
from scipy.spatial.transform import Rotation

from ltc_cli.recordings import rle

#: zlib level of the PNGs: ~10% smaller files than 6 for about twice the encoding time (simulated
#: images are mostly flat). Read at each write, so a test may lower it for speed (same pixels).
PNG_LEVEL = 9


def quat_xyzw(R_world_camera: np.ndarray) -> np.ndarray:
    """Unit quaternion (qx, qy, qz, qw) of a rotation matrix (3, 3), with qw >= 0 (one of the two
    signs, so the same rotation always gives the same text)."""
    q = Rotation.from_matrix(R_world_camera).as_quat()
    return q if q[3] >= 0 else -q


def pose_line(frame_id: str, T_world_camera: np.ndarray) -> str:
    """One poses.txt line: ``frame_id tx ty tz qx qy qz qw`` (full float precision)."""
    q = quat_xyzw(T_world_camera[:3, :3])
    return " ".join([frame_id] + [repr(float(v)) for v in (*T_world_camera[:3, 3], *q)])


def save_png(path, array: np.ndarray) -> None:
    """An 8-bit RGB (H, W, 3), or a 16-bit single-channel (H, W) image as PNG."""
    Image.fromarray(array).save(path, format="PNG", compress_level=PNG_LEVEL)


def folder_bytes(root) -> int:
    """Total size of the files under root."""
    total = 0
    for folder, _, files in os.walk(root):
        total += sum(os.path.getsize(os.path.join(folder, name)) for name in files)
    return total


class RecordingWriter:
    """One ``ltc-recording/1`` folder, written frame by frame.

    ``meta`` is the recording.yaml document (format, camera, depth, classes, ...), written at once in
    the given key order. Each :meth:`write_frame` writes that frame's images and detections; poses.txt
    is written by :meth:`close` (frames in the order written).
    """

    def __init__(self, root, meta: dict):
        self.root = Path(root)
        self.root.mkdir(parents=True, exist_ok=True)
        self._pose_lines: list[str] = []
        self._made: set[str] = set()
        with open(self.root / "recording.yaml", "w", encoding="utf-8") as f:
            yaml.safe_dump(meta, f, sort_keys=False, default_flow_style=None)

    def _file(self, sub: str, name: str) -> Path:
        if sub not in self._made:
            (self.root / sub).mkdir(exist_ok=True)
            self._made.add(sub)
        return self.root / sub / name

    def write_frame(self, frame_id: str, T_world_camera: np.ndarray, rgb: np.ndarray, depth: np.ndarray,
                    annotations: np.ndarray | None = None, instances: list | None = None,
                    detector: str | None = None) -> None:
        """One frame: rgb (H, W, 3) uint8, depth (H, W) uint16 (value / scale = metres, 0 = none),
        optional annotations (H, W) uint16 (ground-truth object ids, 0 = none), optional detections:
        instances are dicts in their file order (class, score, scores, ...) whose ``mask`` is a bool
        array (H, W), written as COCO RLE."""
        self._pose_lines.append(pose_line(frame_id, T_world_camera))
        save_png(self._file("rgb", f"{frame_id}.png"), rgb)
        save_png(self._file("depth", f"{frame_id}.png"), depth)
        if annotations is not None:
            save_png(self._file("annotations", f"{frame_id}.png"), annotations)
        if instances is not None:
            doc = {"frame": frame_id}
            if detector is not None:
                doc["detector"] = detector
            # Replacing the mask keeps each instance's key order.
            doc["instances"] = [{**inst, "mask": rle.encode(inst["mask"])} for inst in instances]
            with open(self._file("detections", f"{frame_id}.json"), "w", encoding="utf-8") as f:
                json.dump(doc, f, separators=(",", ":"))
                f.write("\n")

    def write_ground_truth(self, objects: list[dict], lap: int, changes: dict) -> None:
        """ground_truth.json (ltc-ground-truth/1), one object per line: readable and diffable
        between laps."""
        with open(self.root / "ground_truth.json", "w", encoding="utf-8") as f:
            f.write('{\n"format": "ltc-ground-truth/1",\n"lap": %d,\n"objects": [\n' % lap)
            f.write(",\n".join(json.dumps(o) for o in objects))
            f.write('\n],\n"changes": %s\n}\n' % json.dumps(changes))

    def close(self) -> int:
        """Write poses.txt; returns the folder's size in bytes."""
        with open(self.root / "poses.txt", "w", encoding="utf-8") as f:
            f.write("\n".join(self._pose_lines) + "\n")
        return folder_bytes(self.root)

"""Reader of the native ``ltc-recording/1`` layout (DESIGN.md section 3)."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import yaml

from ltc_cli import hookimpl
from ltc_cli.errors import FrameError, RecordingError
from ltc_cli.types import Intrinsics, Recording
from ltc_cli.validation import check_options, validate
from ltc_plugins.readers.common import (
    FrameSource, ImageFormat, first_existing, frame_refs, quaternion_pose, up_direction,
)  # fmt: skip

# Everything about the recording is in recording.yaml: the reader takes no options.
OPTIONS_SCHEMA = {"$schema": "https://json-schema.org/draft/2020-12/schema", "type": "object",
                  "additionalProperties": False, "properties": {}}  # fmt: skip


def parse_pose(fields, where: str, path) -> np.ndarray:
    """``tx ty tz qx qy qz qw`` -> T (4, 4); FrameError naming the file and line when it is bad."""
    if len(fields) != 7:
        raise FrameError(f"{where}: expected 7 numbers (tx ty tz qx qy qz qw), got {len(fields)}", path)
    try:
        vals = np.array([float(f) for f in fields])
    except ValueError:
        raise FrameError(f"{where}: not a number in {' '.join(fields)!r}", path) from None
    return quaternion_pose(vals, path, where)


def _read_meta(meta_path: Path) -> tuple[bytes, dict]:
    """recording.yaml's bytes and its schema-checked contents."""
    meta_bytes = meta_path.read_bytes()
    try:
        meta = yaml.safe_load(meta_bytes)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        raise RecordingError(f"not valid YAML{where}", meta_path) from None
    if not isinstance(meta, dict):
        raise RecordingError("must be a YAML mapping", meta_path)
    fmt = meta.get("format")
    if isinstance(fmt, str) and fmt.startswith("ltc-recording/") and fmt != "ltc-recording/1":
        raise RecordingError(f"format {fmt!r}: this version of ltc reads ltc-recording/1 (a newer ltc may read it)",
                             meta_path)
    validate(meta, "recording", meta_path)
    return meta_bytes, meta


def _read_poses(poses_path: Path) -> tuple[str, dict[str, tuple[int, list[str]]], list[str]]:
    """poses.txt's text, {frame id: (line number, the 7 fields)} and the frame ids in file order."""
    try:
        poses_text = poses_path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise RecordingError(f"cannot read ({exc})", poses_path) from None
    poses: dict[str, tuple[int, list[str]]] = {}
    order: list[str] = []
    for lineno, line in enumerate(poses_text.splitlines(), start=1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        fields = line.split()
        key = fields[0]
        if key in poses:
            raise RecordingError(f"line {lineno}: frame {key!r} appears twice", poses_path)
        poses[key] = (lineno, fields[1:])
        order.append(key)
    return poses_text, poses, order


class LtcRecordingReader:
    name = "ltc-recording"
    OPTIONS_SCHEMA = OPTIONS_SCHEMA

    @staticmethod
    def sniff(path) -> bool:
        return (Path(path) / "recording.yaml").is_file()

    @staticmethod
    def open(path, options: dict | None = None) -> Recording:
        root = Path(path)
        check_options(options, OPTIONS_SCHEMA, "reader 'ltc-recording'")
        meta_path = root / "recording.yaml"
        if not root.is_dir():
            raise RecordingError("recording folder does not exist", root)
        if not meta_path.is_file():
            raise RecordingError("recording.yaml is missing (not an ltc-recording/1 folder)", root)
        meta_bytes, meta = _read_meta(meta_path)
        cam = meta["camera"]
        intr = Intrinsics(int(cam["width"]), int(cam["height"]), float(cam["fx"]), float(cam["fy"]),
                          float(cam["cx"]), float(cam["cy"]))
        depth = meta["depth"]
        depth_range = None
        if "min" in depth or "max" in depth:
            depth_range = (float(depth.get("min", 0.0)), float(depth.get("max", 1e9)))
            if depth_range[0] >= depth_range[1]:
                raise RecordingError("depth.min must be below depth.max", meta_path)
        try:
            up = up_direction(meta.get("up"))
        except ValueError as exc:
            raise RecordingError(str(exc), meta_path) from None
        T_robot_camera = None
        if "T_robot_camera" in meta:
            T_robot_camera = parse_pose([str(v) for v in meta["T_robot_camera"]], "T_robot_camera", meta_path)

        poses_path = root / "poses.txt"
        if not poses_path.is_file():
            raise RecordingError("poses.txt is missing", root)
        poses_text, poses, order = _read_poses(poses_path)
        rgb_dir, depth_dir = root / "rgb", root / "depth"
        # Frames with images but no pose line are still listed, so the user hears about them.
        if rgb_dir.is_dir():
            order += sorted(p.stem for p in rgb_dir.iterdir() if p.suffix.lower() in (".png", ".jpg") and p.stem not in poses)
        if not order:
            raise RecordingError("no frames (poses.txt is empty)", poses_path)

        def pose_of(key: str):
            def pose() -> np.ndarray:
                if key not in poses:
                    raise FrameError(f"frame {key!r} has no pose line", poses_path)
                lineno, fields = poses[key]
                T = parse_pose(fields, f"line {lineno}", poses_path)
                return T if T_robot_camera is None else T @ T_robot_camera

            return pose

        def image(folder: Path, key: str, ext: str | None, choices: tuple[str, str]) -> Path:
            return folder / f"{key}.{ext}" if ext else first_existing(*(folder / f"{key}.{e}" for e in choices))

        sources = [
            FrameSource(
                key=key,
                rgb_path=image(rgb_dir, key, meta.get("rgb_ext"), ("png", "jpg")),
                depth_path=image(depth_dir, key, meta.get("depth_ext"), ("png", "pgm")),
                pose=pose_of(key),
            )
            for key in order
        ]
        # Metadata, poses and the depth files' names and sizes: two laps driven along the same path
        # differ in their (compressed) depth images even when their poses are the same.
        listing = ""
        if depth_dir.is_dir():
            listing = "\n".join(f"{p.name} {p.stat().st_size}" for p in sorted(depth_dir.iterdir()))
        digest = hashlib.sha256(meta_bytes + b"\0" + poses_text.encode() + b"\0" + listing.encode())
        return Recording(
            path=str(root), format="ltc-recording/1", identity=digest.hexdigest()[:16], intrinsics=intr,
            frames=frame_refs(sources, ImageFormat(intr, float(depth["scale"]))),
            up=up, classes=meta.get("classes"), depth_range=depth_range, meta=meta,
        )


@hookimpl
def register_readers(register):
    register("ltc-recording", LtcRecordingReader)

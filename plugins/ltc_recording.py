"""Reader of the native ``ltc-recording/1`` layout (DESIGN.md section 3)."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import yaml

from ltc_cli import hookimpl
from ltc_cli.errors import FrameError, RecordingError
from ltc_cli.geometry.camera import is_rotation, pose_matrix
from ltc_cli.recordings.images import load_depth, load_rgb
from ltc_cli.validation import validate
from ltc_cli.types import Frame, FrameRef, Intrinsics, Recording

AXES = {"x": (1, 0, 0), "y": (0, 1, 0), "z": (0, 0, 1)}


def parse_up(value):
    """recording.yaml ``up`` -> None (already z-up), a unit vector (3,), or "estimate"."""
    if value is None:
        return None
    if isinstance(value, str):
        if value == "estimate":
            return value
        sign = -1.0 if value.startswith("-") else 1.0
        vec = sign * np.array(AXES[value.lstrip("+-")], dtype=float)
    else:
        vec = np.asarray(value, dtype=float)
    n = np.linalg.norm(vec)
    if not np.isfinite(n) or n < 1e-9:
        raise ValueError("up must be a non-zero vector")
    vec = vec / n
    return None if np.allclose(vec, [0, 0, 1]) else vec


def parse_pose(fields, where: str, path) -> np.ndarray:
    """``tx ty tz qx qy qz qw`` -> T (4, 4); FrameError naming the file and line when it is bad."""
    if len(fields) != 7:
        raise FrameError(f"{where}: expected 7 numbers (tx ty tz qx qy qz qw), got {len(fields)}", path)
    try:
        vals = np.array([float(f) for f in fields])
    except ValueError:
        raise FrameError(f"{where}: not a number in {' '.join(fields)!r}", path) from None
    if not np.all(np.isfinite(vals)):
        raise FrameError(f"{where}: pose is not finite", path)
    q = vals[3:]
    norm = float(np.linalg.norm(q))
    # A quaternion far from unit length is not a rotation written with rounding: refuse it rather
    # than guess.
    if not 0.99 <= norm <= 1.01:
        raise FrameError(f"{where}: quaternion norm is {norm:.4g}, not a rotation", path)
    T = pose_matrix(vals[:3], q / norm)
    if not is_rotation(T[:3, :3]):
        raise FrameError(f"{where}: not a rotation", path)
    return T


class LtcRecordingReader:
    name = "ltc-recording"

    @staticmethod
    def sniff(path) -> bool:
        return (Path(path) / "recording.yaml").is_file()

    @staticmethod
    def open(path, options: dict | None = None) -> Recording:
        root = Path(path)
        meta_path = root / "recording.yaml"
        if not root.is_dir():
            raise RecordingError("recording folder does not exist", root)
        if not meta_path.is_file():
            raise RecordingError("recording.yaml is missing (not an ltc-recording/1 folder)", root)
        meta_bytes = meta_path.read_bytes()
        try:
            meta = yaml.safe_load(meta_bytes)
        except yaml.YAMLError as exc:
            mark = getattr(exc, "problem_mark", None)
            where = f" at line {mark.line + 1}" if mark is not None else ""
            raise RecordingError(f"not valid YAML{where}", meta_path) from None
        if not isinstance(meta, dict):
            raise RecordingError("must be a YAML mapping", meta_path)
        validate(meta, "recording", meta_path)
        cam = meta["camera"]
        intr = Intrinsics(int(cam["width"]), int(cam["height"]), float(cam["fx"]), float(cam["fy"]),
                          float(cam["cx"]), float(cam["cy"]))
        depth = meta["depth"]
        scale = float(depth["scale"])
        depth_range = None
        if "min" in depth or "max" in depth:
            depth_range = (float(depth.get("min", 0.0)), float(depth.get("max", 1e9)))
            if depth_range[0] >= depth_range[1]:
                raise RecordingError("depth.min must be below depth.max", meta_path)
        try:
            up = parse_up(meta.get("up"))
        except ValueError as exc:
            raise RecordingError(str(exc), meta_path) from None
        T_robot_camera = None
        if "T_robot_camera" in meta:
            T_robot_camera = parse_pose([str(v) for v in meta["T_robot_camera"]], "T_robot_camera", meta_path)

        poses_path = root / "poses.txt"
        if not poses_path.is_file():
            raise RecordingError("poses.txt is missing", root)
        try:
            poses_text = poses_path.read_text()
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
        rgb_dir, depth_dir = root / "rgb", root / "depth"
        rgb_ext = meta.get("rgb_ext")
        depth_ext = meta.get("depth_ext")
        # Frames with images but no pose line are still listed, so the user hears about them.
        if rgb_dir.is_dir():
            extra = sorted(p.stem for p in rgb_dir.iterdir() if p.suffix.lower() in (".png", ".jpg") and p.stem not in poses)
            order += extra
        if not order:
            raise RecordingError("no frames (poses.txt is empty)", poses_path)

        def find(folder: Path, key: str, ext, choices):
            if ext:
                return folder / f"{key}.{ext}"
            for e in choices:
                p = folder / f"{key}.{e}"
                if p.is_file():
                    return p
            return folder / f"{key}.{choices[0]}"

        def make_loader(index: int, key: str):
            def load() -> Frame:
                if key not in poses:
                    raise FrameError(f"frame {key!r} has no pose line", poses_path)
                lineno, fields = poses[key]
                T = parse_pose(fields, f"line {lineno}", poses_path)
                if T_robot_camera is not None:
                    T = T @ T_robot_camera
                rgb_path = find(rgb_dir, key, rgb_ext, ("png", "jpg"))
                depth_path = find(depth_dir, key, depth_ext, ("png", "pgm"))
                rgb = load_rgb(rgb_path, intr.width, intr.height)
                depth_m = load_depth(depth_path, scale, intr.width, intr.height)
                return Frame(key, index, depth_m, T, intr, rgb, str(rgb_path), str(depth_path))

            return load

        frames = [FrameRef(key, i, make_loader(i, key)) for i, key in enumerate(order)]
        # Metadata, poses and the depth files' names and sizes: two laps driven along the same path
        # differ in their (compressed) depth images even when their poses are the same.
        listing = ""
        if depth_dir.is_dir():
            listing = "\n".join(f"{p.name} {p.stat().st_size}" for p in sorted(depth_dir.iterdir()))
        digest = hashlib.sha256(meta_bytes + b"\0" + poses_text.encode() + b"\0" + listing.encode())
        identity = digest.hexdigest()[:16]
        return Recording(
            path=str(root), format="ltc-recording/1", identity=identity, intrinsics=intr, frames=frames,
            up=up, classes=meta.get("classes"), depth_range=depth_range, meta=meta,
        )


@hookimpl
def register_readers(register):
    register("ltc-recording", LtcRecordingReader)

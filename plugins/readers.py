"""Readers for RGB-D layouts users already have (DESIGN.md section 3): TUM RGB-D, 7-Scenes / 3DMatch
and the ScanNet export layout.

Each reader has ``sniff(path) -> bool`` (cheap, never raises) and ``open(path, options) ->
Recording``. Opening parses the index and pose files only; images are read by each frame's lazy
``load()``, which also checks the pose and raises :class:`FrameError` naming the file at fault, so a
bad frame is skipped and counted instead of ending the ingest.

Options common to all readers (all optional):

- ``depth_scale``: metres = stored value / depth_scale (TUM 5000, 7-Scenes and ScanNet 1000).
- ``intrinsics``: ``{fx, fy, cx, cy}`` (or a list in that order) overriding the layout's camera.
- ``up``: the world's up direction: ``"estimate"``, ``null`` (already z-up), an axis name such as
  ``"-y"`` or a 3-vector; overrides the layout's default (TUM and 7-Scenes: estimate; ScanNet: z-up).

TUM also takes ``camera`` (``fr1``, ``fr2``, ``fr3`` or ``ros``), ``poses`` (a trajectory file in the
TUM format to use instead of groundtruth.txt, relative to the recording), ``max_time_diff``
(seconds, default 0.02) and ``max_pose_gap`` (seconds, default 0.1).

A recording's ``identity`` hashes the layout's index, intrinsics and pose files (names and bytes),
never the folder's path, so a recording moved elsewhere keeps its identity and frame keys.
"""

from __future__ import annotations

import hashlib
import math
import re
from pathlib import Path
from typing import Callable, Iterable

import numpy as np
from PIL import Image

from ltc_cli import hookimpl
from ltc_cli.errors import ConfigError, FrameError, RecordingError
from ltc_cli.geometry.camera import is_rotation, quat_to_rot
from ltc_cli.recordings.images import load_depth, load_rgb
from ltc_cli.types import Frame, FrameRef, Intrinsics, Recording

# A quaternion further than this from unit norm is a corrupt pose, not rounding in a text file.
QUAT_NORM_RANGE = (0.99, 1.01)
# Rotation matrices in text files carry 6-7 significant digits; 1e-2 accepts that and still rejects
# scaled or sheared matrices. Accepted ones are re-orthonormalised.
ROTATION_TOL = 1e-2

COMMON_OPTIONS = ("depth_scale", "intrinsics", "up")

AXES = {
    "+x": (1.0, 0.0, 0.0), "x": (1.0, 0.0, 0.0), "-x": (-1.0, 0.0, 0.0),
    "+y": (0.0, 1.0, 0.0), "y": (0.0, 1.0, 0.0), "-y": (0.0, -1.0, 0.0),
    "+z": (0.0, 0.0, 1.0), "z": (0.0, 0.0, 1.0), "-z": (0.0, 0.0, -1.0),
}  # fmt: skip


# --------------------------------------------------------------------------------------------------
# Shared helpers


def _open_folder(path, options, known, reader: str):
    """(folder, checked options) of a recording about to be opened."""
    folder = Path(path)
    opts = _check_options(options, known, reader)
    if not folder.is_dir():
        raise RecordingError("recording folder does not exist", folder)
    return folder, opts


def _check_options(options: dict | None, allowed: Iterable[str], reader: str) -> dict:
    options = dict(options or {})
    unknown = sorted(set(options) - set(allowed))
    if unknown:
        raise ConfigError(
            f"unknown option(s) {', '.join(map(repr, unknown))} for reader {reader!r} "
            f"(known: {', '.join(sorted(allowed))})"
        )
    return options


def _positive_number(options: dict, key: str, default: float, reader: str) -> float:
    value = options.get(key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
        math.isfinite(value) and value > 0
    ):
        raise ConfigError(f"reader {reader!r}: option {key!r} must be a positive number, got {value!r}")
    return float(value)


def _intrinsics_option(options: dict, reader: str) -> tuple[float, float, float, float] | None:
    """The ``intrinsics`` override as (fx, fy, cx, cy), or None when not given."""
    value = options.get("intrinsics")
    if value is None:
        return None
    keys = ("fx", "fy", "cx", "cy")
    if isinstance(value, dict):
        missing = [k for k in keys if k not in value]
        extra = sorted(set(value) - set(keys))
        if missing or extra:
            raise ConfigError(
                f"reader {reader!r}: option 'intrinsics' needs exactly fx, fy, cx, cy"
                + (f" (missing {', '.join(missing)})" if missing else "")
                + (f" (unknown {', '.join(extra)})" if extra else "")
            )
        vals = [value[k] for k in keys]
    elif isinstance(value, (list, tuple)) and len(value) == 4:
        vals = list(value)
    else:
        raise ConfigError(
            f"reader {reader!r}: option 'intrinsics' must be {{fx, fy, cx, cy}} or a list of 4 numbers"
        )
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in vals):
        raise ConfigError(f"reader {reader!r}: option 'intrinsics' must hold finite numbers, got {value!r}")
    if vals[0] <= 0 or vals[1] <= 0:
        raise ConfigError(f"reader {reader!r}: focal lengths fx, fy must be positive, got {value!r}")
    return tuple(float(v) for v in vals)


def _up_option(options: dict, default, reader: str):
    """The ``up`` option as Recording.up wants it: None (z-up), "estimate" or a unit 3-tuple."""
    if "up" not in options:
        return default
    value = options["up"]
    if value is None or value == "estimate":
        return value
    if isinstance(value, str):
        if value.strip().lower() not in AXES:
            raise ConfigError(
                f"reader {reader!r}: option 'up' must be 'estimate', an axis like '-y', or a 3-vector, "
                f"got {value!r}"
            )
        vec = AXES[value.strip().lower()]
        return None if vec == (0.0, 0.0, 1.0) else vec
    try:
        vec = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        vec = np.zeros(0)
    if vec.shape != (3,) or not np.all(np.isfinite(vec)) or np.linalg.norm(vec) < 1e-9:
        raise ConfigError(f"reader {reader!r}: option 'up' must be a non-zero 3-vector, got {value!r}")
    return tuple(float(v) for v in vec / np.linalg.norm(vec))


def _make_intrinsics(width, height, fx_fy_cx_cy, override) -> Intrinsics:
    fx, fy, cx, cy = override if override is not None else fx_fy_cx_cy
    return Intrinsics(int(width), int(height), float(fx), float(fy), float(cx), float(cy))


def _identity(files: Iterable[tuple[str, bytes]]) -> str:
    """sha256 (first 16 hex digits) of (relative name, bytes) pairs: location-independent."""
    h = hashlib.sha256()
    for name, data in files:
        name_b = name.encode("utf-8")
        # Length prefixes: no two different file lists hash the same byte stream.
        h.update(len(name_b).to_bytes(8, "little") + name_b)
        h.update(len(data).to_bytes(8, "little") + data)
    return h.hexdigest()[:16]


def _read_bytes(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except OSError as exc:
        raise RecordingError(f"cannot read file ({exc.strerror or exc})", path) from None


def _image_size(path: Path) -> tuple[int, int]:
    """(width, height) from an image header, without decoding the pixels."""
    try:
        with Image.open(path) as img:
            return img.size
    except (OSError, ValueError, SyntaxError) as exc:
        raise RecordingError(
            f"cannot read image to find the camera's size ({exc.__class__.__name__}: {exc})", path
        ) from None


def _first_size(paths: Iterable[Path], folder: Path) -> tuple[int, int]:
    """The image size of the first existing file among ``paths`` (the camera's resolution)."""
    for p in paths:
        if p.is_file():
            return _image_size(p)
    raise RecordingError("no depth image of any frame exists", folder)


def _checked_matrix_pose(T: np.ndarray, path: Path) -> np.ndarray:
    """Validate a 4x4 camera-to-world pose; returns it with its rotation re-orthonormalised."""
    if T.shape != (4, 4):
        raise FrameError(f"pose must be a 4x4 matrix, got {T.size} numbers", path)
    if not np.all(np.isfinite(T)):
        # ScanNet writes -inf poses for frames its tracker lost.
        raise FrameError("pose has non-finite values (frame without a valid pose)", path)
    if np.abs(T[3] - [0.0, 0.0, 0.0, 1.0]).max() > 1e-3:
        raise FrameError(f"pose's last row must be 0 0 0 1, got {T[3].tolist()}", path)
    R = T[:3, :3]
    if not is_rotation(R, tol=ROTATION_TOL):
        raise FrameError("pose's 3x3 part is not a rotation matrix", path)
    U, _, Vt = np.linalg.svd(R)
    out = np.array(T, dtype=np.float64)
    out[:3, :3] = U @ Vt
    out[3] = [0.0, 0.0, 0.0, 1.0]
    return out


def _read_matrix_pose(path: Path) -> np.ndarray:
    """Read a text file holding a 4x4 matrix (16 numbers, any whitespace); raises FrameError."""
    if not path.is_file():
        raise FrameError("pose file is missing", path)
    try:
        tokens = path.read_text(encoding="utf-8", errors="replace").split()
        values = np.array([float(t) for t in tokens], dtype=np.float64)
    except (OSError, ValueError) as exc:
        raise FrameError(f"cannot read pose as numbers ({exc})", path) from None
    if values.size != 16:
        raise FrameError(f"pose must be a 4x4 matrix, got {values.size} numbers", path)
    return _checked_matrix_pose(values.reshape(4, 4), path)


def _read_matrix_file(path: Path, what: str) -> np.ndarray:
    """An intrinsics matrix file (3x3 or 4x4) as numbers; raises RecordingError."""
    try:
        values = np.array([float(t) for t in path.read_text(encoding="utf-8").split()])
    except (OSError, ValueError) as exc:
        raise RecordingError(f"cannot read {what} as numbers ({exc})", path) from None
    if values.size not in (9, 16) or not np.all(np.isfinite(values)):
        raise RecordingError(f"{what} must be a 3x3 or 4x4 matrix of finite numbers", path)
    n = 3 if values.size == 9 else 4
    K = values.reshape(n, n)
    if K[0, 0] <= 0 or K[1, 1] <= 0:
        raise RecordingError(f"{what} has non-positive focal lengths", path)
    return K


def _load_rgb_resized(path: Path, width: int, height: int) -> np.ndarray:
    """Colour image resized to (width, height) when it differs (ScanNet colour vs depth)."""
    rgb = load_rgb(path)
    if rgb.shape[1] != width or rgb.shape[0] != height:
        rgb = np.asarray(Image.fromarray(rgb).resize((width, height), Image.BILINEAR))
    return rgb


def _frame_loader(
    key: str,
    index: int,
    rgb_path: Path,
    depth_path: Path,
    pose_fn: Callable[[], np.ndarray],
    intr: Intrinsics,
    depth_scale: float,
    resize_rgb: bool = False,
    invalid_raw: int | None = None,
    extra: dict | None = None,
) -> Callable[[], Frame]:
    """A ``load()`` closure: pose first (cheap, the usual failure), then depth, then colour."""

    def load() -> Frame:
        T_world_camera = pose_fn()
        depth_m = load_depth(depth_path, depth_scale, intr.width, intr.height)
        if invalid_raw is not None:
            # 7-Scenes marks missing readings with 65535, not 0.
            depth_m[depth_m >= (invalid_raw - 0.5) / depth_scale] = 0.0
        if resize_rgb:
            rgb = _load_rgb_resized(rgb_path, intr.width, intr.height)
        else:
            rgb = load_rgb(rgb_path, intr.width, intr.height)
        return Frame(
            key=key,
            index=index,
            depth_m=depth_m,
            T_world_camera=T_world_camera,
            intrinsics=intr,
            rgb=rgb,
            rgb_path=str(rgb_path),
            depth_path=str(depth_path),
            extra=dict(extra or {}),
        )

    return load


# --------------------------------------------------------------------------------------------------
# TUM RGB-D

# Calibrated pinhole parameters of the Freiburg sensors (TUM RGB-D "file formats" page) and the ROS
# default the TUM authors recommend when the depth was registered without undistortion.
TUM_CAMERAS = {
    "fr1": (517.3, 516.5, 318.6, 255.3),
    "fr2": (520.9, 521.0, 325.1, 249.7),
    "fr3": (535.4, 539.2, 320.1, 247.6),
    "ros": (525.0, 525.0, 319.5, 239.5),
}
_TUM_FOLDER = re.compile(r"freiburg([123])", re.IGNORECASE)


def _tum_list(path: Path, columns: int, what: str) -> tuple[list[str], list[list[str]], list[int]]:
    """Parse a TUM list file: (stamp strings, the other columns, 1-based line numbers)."""
    if not path.is_file():
        raise RecordingError(f"TUM recording has no {path.name}", path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise RecordingError(f"cannot read {what} ({exc})", path) from None
    stamps, rest, lines = [], [], []
    for lineno, line in enumerate(text.splitlines(), 1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        parts = line.replace(",", " ").split()
        if len(parts) != columns:
            raise RecordingError(
                f"line {lineno}: expected {columns} columns ({what}), got {len(parts)}", path
            )
        try:
            float(parts[0])
        except ValueError:
            raise RecordingError(f"line {lineno}: timestamp {parts[0]!r} is not a number", path) from None
        stamps.append(parts[0])
        rest.append(parts[1:])
        lines.append(lineno)
    return stamps, rest, lines


def _nearest(sorted_stamps: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Index of the nearest of ``sorted_stamps`` (M,) for each of ``t`` (N,)."""
    i = np.clip(np.searchsorted(sorted_stamps, t), 1, len(sorted_stamps) - 1)
    left, right = sorted_stamps[i - 1], sorted_stamps[i]
    return np.where(np.abs(t - left) <= np.abs(right - t), i - 1, i)


def _slerp(q0: np.ndarray, q1: np.ndarray, a: float) -> np.ndarray:
    """Spherical interpolation of unit quaternions (x, y, z, w), shortest arc."""
    dot = float(q0 @ q1)
    if dot < 0:
        q1, dot = -q1, -dot
    if dot > 0.9995:  # nearly equal: lerp is exact enough and avoids dividing by sin(~0)
        q = q0 + a * (q1 - q0)
        return q / np.linalg.norm(q)
    theta = math.acos(dot)
    s = math.sin(theta)
    return (math.sin((1 - a) * theta) * q0 + math.sin(a * theta) * q1) / s


class TumReader:
    """TUM RGB-D: rgb.txt, depth.txt, groundtruth.txt (timestamp tx ty tz qx qy qz qw); depth / 5000.

    Each line of rgb.txt is a frame when a depth image lies within ``max_time_diff`` seconds of it
    (nearest, each depth image used once) and the trajectory covers its timestamp: the pose is
    interpolated (linear translation, slerp rotation) between the two bracketing trajectory stamps
    when they are at most ``max_pose_gap`` apart, else the nearest stamp within ``max_time_diff`` is
    used. Other rgb lines are left out (counted in ``meta["unassociated"]``): TUM sequences usually
    start before the motion capture does.
    """

    name = "tum"
    OPTIONS = COMMON_OPTIONS + ("camera", "poses", "max_time_diff", "max_pose_gap")

    def sniff(self, path) -> bool:
        try:
            p = Path(path)
            return (p / "rgb.txt").is_file() and (p / "depth.txt").is_file()
        except OSError:
            return False

    def open(self, path, options: dict | None = None) -> Recording:
        folder, opts = _open_folder(path, options, self.OPTIONS, self.name)
        depth_scale = _positive_number(opts, "depth_scale", 5000.0, self.name)
        max_dt = _positive_number(opts, "max_time_diff", 0.02, self.name)
        max_gap = _positive_number(opts, "max_pose_gap", 0.1, self.name)
        camera = opts.get("camera")
        if camera is None:
            m = _TUM_FOLDER.search(folder.resolve().name)
            camera = f"fr{m.group(1)}" if m else "ros"
        if camera not in TUM_CAMERAS:
            raise ConfigError(
                f"reader 'tum': option 'camera' must be one of {', '.join(TUM_CAMERAS)}, got {camera!r}"
            )
        poses_path = folder / opts.get("poses", "groundtruth.txt")

        rgb_file, depth_file = folder / "rgb.txt", folder / "depth.txt"
        rgb_stamps, rgb_rest, _ = _tum_list(rgb_file, 2, "timestamp filename")
        depth_stamps, depth_rest, _ = _tum_list(depth_file, 2, "timestamp filename")
        if not poses_path.is_file():
            raise RecordingError(
                "TUM recording has no trajectory: ltc needs camera poses "
                "(groundtruth.txt, or a TUM-format file given with the reader option 'poses')",
                poses_path,
            )
        gt_stamps_s, gt_rest, gt_lines = _tum_list(poses_path, 8, "timestamp tx ty tz qx qy qz qw")
        try:
            # Non-finite values ("nan") parse here and are refused per frame by load().
            gt = np.array(gt_rest, dtype=np.float64).reshape(-1, 7)
        except ValueError:
            raise RecordingError("pose values must be numbers", poses_path) from None
        if not rgb_stamps or not depth_stamps or not gt_stamps_s:
            empty = rgb_file if not rgb_stamps else depth_file if not depth_stamps else poses_path
            raise RecordingError("file lists no entries", empty)

        # Sort the trajectory by time (it normally is already) to bracket stamps by bisection.
        gt_t = np.array([float(s) for s in gt_stamps_s])
        order = np.argsort(gt_t, kind="stable")
        gt_t, gt = gt_t[order], gt[order]
        gt_lines = [gt_lines[i] for i in order]

        rgb_t = np.array([float(s) for s in rgb_stamps])
        depth_t = np.array([float(s) for s in depth_stamps])
        d_order = np.argsort(depth_t, kind="stable")
        depth_sorted = depth_t[d_order]
        if len(depth_sorted) == 1:
            nearest_d = np.zeros(len(rgb_t), dtype=int)
        else:
            nearest_d = _nearest(depth_sorted, rgb_t)
        d_idx = d_order[nearest_d]
        d_diff = np.abs(depth_t[d_idx] - rgb_t)
        ok = d_diff <= max_dt
        # One depth image per rgb frame: when two rgb stamps pick the same depth, keep the closer.
        best_for_depth: dict[int, int] = {}
        for i in np.flatnonzero(ok):
            j = int(d_idx[i])
            if j not in best_for_depth or d_diff[i] < d_diff[best_for_depth[j]]:
                best_for_depth[j] = int(i)
        chosen = sorted(best_for_depth.values())

        # Pose source per frame: (i0, i1, a) interpolation weights into the trajectory.
        pose_src = {}
        for i in chosen:
            t = rgb_t[i]
            k = int(np.searchsorted(gt_t, t))
            if 0 < k < len(gt_t) and gt_t[k] - gt_t[k - 1] <= max_gap:
                i0, i1 = k - 1, k
                span = gt_t[i1] - gt_t[i0]
                a = 0.0 if span <= 0 else float((t - gt_t[i0]) / span)
                pose_src[i] = (i0, i1, a)
            elif k < len(gt_t) and gt_t[k] == t:
                pose_src[i] = (k, k, 0.0)
            else:
                near = [j for j in (k - 1, k) if 0 <= j < len(gt_t)]
                j = min(near, key=lambda j: abs(gt_t[j] - t))
                if abs(gt_t[j] - t) <= max_dt:
                    pose_src[i] = (j, j, 0.0)
        frames_idx = [i for i in chosen if i in pose_src]
        if not frames_idx:
            raise RecordingError(
                f"no rgb.txt entry has a depth image within {max_dt} s and a pose in {poses_path.name}",
                folder,
            )

        def pose_fn(i0: int, i1: int, a: float) -> Callable[[], np.ndarray]:
            def get() -> np.ndarray:
                qs = []
                for j in (i0, i1):
                    row = gt[j]
                    where = f"{poses_path} (line {gt_lines[j]})"
                    if not np.all(np.isfinite(row)):
                        raise FrameError("pose has non-finite values", where)
                    qn = float(np.linalg.norm(row[3:]))
                    if not QUAT_NORM_RANGE[0] <= qn <= QUAT_NORM_RANGE[1]:
                        raise FrameError(f"pose quaternion has norm {qn:.4f}, not 1", where)
                    qs.append(row[3:] / qn)
                t_xyz = (1 - a) * gt[i0, :3] + a * gt[i1, :3]
                q = qs[0] if i0 == i1 else _slerp(qs[0], qs[1], a)
                T = np.eye(4)
                T[:3, :3] = quat_to_rot(q)
                T[:3, 3] = t_xyz
                return T

            return get

        intr_override = _intrinsics_option(opts, self.name)
        width, height = _first_size(
            (folder / depth_rest[int(d_idx[i])][0] for i in frames_idx), folder
        )
        intr = _make_intrinsics(width, height, TUM_CAMERAS[camera], intr_override)

        frames = []
        for index, i in enumerate(frames_idx):
            key = rgb_stamps[i]
            rgb_path = folder / rgb_rest[i][0]
            depth_path = folder / depth_rest[int(d_idx[i])][0]
            load = _frame_loader(
                key, index, rgb_path, depth_path, pose_fn(*pose_src[i]), intr, depth_scale,
                extra={"timestamp": float(rgb_t[i]), "depth_timestamp": float(depth_t[d_idx[i]])},
            )  # fmt: skip
            frames.append(FrameRef(key=key, index=index, load=load))

        identity = _identity(
            (p.name, _read_bytes(p)) for p in (rgb_file, depth_file, poses_path)
        )
        return Recording(
            path=str(folder),
            format="tum",
            identity=identity,
            intrinsics=intr,
            frames=frames,
            up=_up_option(opts, "estimate", self.name),
            meta={
                "reader": self.name,
                "camera": camera if intr_override is None else "custom",
                "depth_scale": depth_scale,
                "poses_file": poses_path.name,
                "unassociated": len(rgb_stamps) - len(frames_idx),
            },
        )


# --------------------------------------------------------------------------------------------------
# 7-Scenes / 3DMatch

SEVEN_SCENES_DEFAULT = (585.0, 585.0, 320.0, 240.0)
_FRAME_POSE = re.compile(r"^(frame-\d+)\.pose\.txt$")


def _seven_scenes_frames(folder: Path) -> list[str]:
    """Frame stems ("frame-000000") of a folder, in numeric order."""
    try:
        names = [m.group(1) for p in folder.iterdir() if (m := _FRAME_POSE.match(p.name))]
    except OSError:
        return []
    return sorted(names, key=lambda s: (int(s.split("-")[1]), s))


def _seq_folders(folder: Path) -> list[Path]:
    try:
        return sorted(
            p for p in folder.iterdir()
            if p.is_dir() and p.name.startswith("seq") and _seven_scenes_frames(p)
        )  # fmt: skip
    except OSError:
        return []


class SevenScenesReader:
    """7-Scenes / 3DMatch: one folder of ``frame-NNNNNN.{color.png|color.jpg,depth.png,pose.txt}``.

    Depth is in millimetres (65535 = no reading in 7-Scenes, mapped to 0); poses are 4x4
    camera-to-world. ``camera-intrinsics.txt`` (3x3 K) is looked for in the folder and then in its
    parent (3DMatch keeps it beside the seq-XX folders); without it the 7-Scenes Kinect default
    (fx = fy = 585, cx = 320, cy = 240) applies. Sequences are never merged: each seq-XX folder is a
    recording of its own (their poses need not share a world frame).
    """

    name = "7scenes"
    OPTIONS = COMMON_OPTIONS

    def sniff(self, path) -> bool:
        try:
            p = Path(path)
            # A scene folder holding seq-XX folders is claimed too, so open() can say which to give.
            return p.is_dir() and (bool(_seven_scenes_frames(p)) or bool(_seq_folders(p)))
        except OSError:
            return False

    def open(self, path, options: dict | None = None) -> Recording:
        folder, opts = _open_folder(path, options, self.OPTIONS, self.name)
        stems = _seven_scenes_frames(folder)
        if not stems:
            seqs = _seq_folders(folder)
            if seqs:
                raise RecordingError(
                    "this folder holds sequences, not frames; give one sequence folder per recording: "
                    + ", ".join(p.name for p in seqs),
                    folder,
                )
            raise RecordingError("no frame-NNNNNN.pose.txt files in the folder", folder)
        depth_scale = _positive_number(opts, "depth_scale", 1000.0, self.name)

        intr_file = next(
            (d / "camera-intrinsics.txt" for d in (folder, folder.parent)
             if (d / "camera-intrinsics.txt").is_file()),
            None,
        )  # fmt: skip
        if intr_file is not None:
            K = _read_matrix_file(intr_file, "camera intrinsics")
            default_cam = (K[0, 0], K[1, 1], K[0, 2], K[1, 2])
        else:
            default_cam = SEVEN_SCENES_DEFAULT
        width, height = _first_size((folder / f"{s}.depth.png" for s in stems), folder)
        intr = _make_intrinsics(width, height, default_cam, _intrinsics_option(opts, self.name))

        frames = []
        pose_files = []
        for index, stem in enumerate(stems):
            pose_path = folder / f"{stem}.pose.txt"
            pose_files.append((pose_path.name, _read_bytes(pose_path)))
            rgb_path = folder / f"{stem}.color.png"
            if not rgb_path.is_file() and (folder / f"{stem}.color.jpg").is_file():
                rgb_path = folder / f"{stem}.color.jpg"
            load = _frame_loader(
                stem, index, rgb_path, folder / f"{stem}.depth.png",
                (lambda p=pose_path: _read_matrix_pose(p)), intr, depth_scale, invalid_raw=65535,
            )  # fmt: skip
            frames.append(FrameRef(key=stem, index=index, load=load))

        meta_files = [(intr_file.name, _read_bytes(intr_file))] if intr_file is not None else []
        return Recording(
            path=str(folder),
            format="7scenes",
            identity=_identity(meta_files + pose_files),
            intrinsics=intr,
            frames=frames,
            up=_up_option(opts, "estimate", self.name),
            meta={
                "reader": self.name,
                "depth_scale": depth_scale,
                "intrinsics_file": str(intr_file) if intr_file is not None else None,
            },
        )


# --------------------------------------------------------------------------------------------------
# ScanNet export (SensReader output)


def _numbered(folder: Path, ext: str) -> list[str]:
    """Stems of ``N.<ext>`` files in numeric order."""
    try:
        stems = [p.stem for p in folder.iterdir() if p.suffix == ext and p.stem.isdigit()]
    except OSError:
        return []
    return sorted(stems, key=int)


class ScanNetReader:
    """ScanNet export: ``color/N.jpg``, ``depth/N.png`` (mm), ``pose/N.txt`` (4x4 camera-to-world),
    ``intrinsic/intrinsic_depth.txt`` (4x4).

    Frames are at the depth camera's resolution and intrinsics; colour (often 1296x968) is resized to
    it. Frames whose pose is ``-inf`` (lost tracking) raise FrameError when loaded. ScanNet worlds are
    z-up, so ``up`` defaults to None.
    """

    name = "scannet"
    OPTIONS = COMMON_OPTIONS

    def sniff(self, path) -> bool:
        try:
            p = Path(path)
            return all((p / d).is_dir() for d in ("color", "depth", "pose")) and (
                (p / "intrinsic").is_dir()
            )
        except OSError:
            return False

    def open(self, path, options: dict | None = None) -> Recording:
        folder, opts = _open_folder(path, options, self.OPTIONS, self.name)
        for d in ("color", "depth", "pose"):
            if not (folder / d).is_dir():
                raise RecordingError(f"ScanNet export has no {d}/ folder", folder)
        depth_scale = _positive_number(opts, "depth_scale", 1000.0, self.name)
        override = _intrinsics_option(opts, self.name)
        intr_file = folder / "intrinsic" / "intrinsic_depth.txt"
        meta_files = []
        if intr_file.is_file():
            K = _read_matrix_file(intr_file, "depth intrinsics")
            default_cam = (K[0, 0], K[1, 1], K[0, 2], K[1, 2])
            meta_files.append(("intrinsic/intrinsic_depth.txt", _read_bytes(intr_file)))
        elif override is None:
            raise RecordingError(
                "ScanNet export has no intrinsic/intrinsic_depth.txt (or give the reader option "
                "'intrinsics')",
                intr_file,
            )
        else:
            default_cam = override
        stems = _numbered(folder / "pose", ".txt")
        if not stems:
            raise RecordingError("no pose/N.txt files", folder / "pose")
        width, height = _first_size((folder / "depth" / f"{s}.png" for s in stems), folder)
        intr = _make_intrinsics(width, height, default_cam, override)

        frames = []
        pose_files = []
        for index, stem in enumerate(stems):
            pose_path = folder / "pose" / f"{stem}.txt"
            pose_files.append((f"pose/{stem}.txt", _read_bytes(pose_path)))
            rgb_path = folder / "color" / f"{stem}.jpg"
            if not rgb_path.is_file() and (folder / "color" / f"{stem}.png").is_file():
                rgb_path = folder / "color" / f"{stem}.png"
            load = _frame_loader(
                stem, index, rgb_path, folder / "depth" / f"{stem}.png",
                (lambda p=pose_path: _read_matrix_pose(p)), intr, depth_scale, resize_rgb=True,
            )  # fmt: skip
            frames.append(FrameRef(key=stem, index=index, load=load))

        return Recording(
            path=str(folder),
            format="scannet",
            identity=_identity(meta_files + pose_files),
            intrinsics=intr,
            frames=frames,
            up=_up_option(opts, None, self.name),
            meta={"reader": self.name, "depth_scale": depth_scale},
        )


READERS = (TumReader(), SevenScenesReader(), ScanNetReader())


@hookimpl
def register_readers(register):
    for reader in READERS:
        register(reader.name, reader)

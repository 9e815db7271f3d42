"""TUM RGB-D reader: rgb.txt, depth.txt, groundtruth.txt (timestamp tx ty tz qx qy qz qw); depth / 5000."""

from __future__ import annotations

import io
import re
import threading
import warnings
from pathlib import Path
from typing import Callable

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from ltc_cli.errors import RecordingError
from ltc_cli.types import Recording
from ltc_plugins.readers.common import (
    FrameSource, ImageFormat, associate_nearest, first_size, frame_refs, identity, intrinsics_option,
    QUAT_NORM_RANGE, make_intrinsics, open_folder, options_schema, quaternion_pose, read_bytes, up_option,
)  # fmt: skip

# Calibrated pinhole parameters of the Freiburg sensors (TUM RGB-D "file formats" page) and the ROS
# default the TUM authors recommend when the depth was registered without undistortion.
TUM_CAMERAS = {
    "fr1": (517.3, 516.5, 318.6, 255.3),
    "fr2": (520.9, 521.0, 325.1, 249.7),
    "fr3": (535.4, 539.2, 320.1, 247.6),
    "ros": (525.0, 525.0, 319.5, 239.5),
}
_TUM_FOLDER = re.compile(r"freiburg([123])", re.IGNORECASE)

_SECONDS = {"type": "number", "exclusiveMinimum": 0}
OPTIONS_SCHEMA = options_schema(
    5000.0,
    "estimate",
    camera={"enum": [None, *TUM_CAMERAS], "default": None,
            "description": "the sensor's calibration; default from the folder name (freiburgN), else ros"},
    poses={"type": "string", "minLength": 1, "default": "groundtruth.txt",
           "description": "trajectory file (TUM format) relative to the recording"},
    max_time_diff={**_SECONDS, "default": 0.02, "description": "seconds between associated stamps"},
    max_pose_gap={**_SECONDS, "default": 0.1, "description": "largest trajectory gap to interpolate over"},
)  # fmt: skip


def _tum_list(path: Path, columns: int, what: str) -> tuple[list[str], list[list[str]], list[int]]:
    """Parse a TUM list file: (stamp strings, the other columns, 1-based line numbers)."""
    if not path.is_file():
        raise RecordingError(f"TUM recording has no {path.name}", path)
    try:
        text = path.read_text(encoding="utf-8-sig")
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


def _trajectory(path: Path) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """A TUM trajectory file: stamps (N,), rows tx ty tz qx qy qz qw (N, 7), and each row's line
    number. numpy reads a file of eight numbers a line at once: a motion-capture trajectory has a
    hundred rows a second, and line by line, a 100,000-frame recording's took 4.5 s. Anything else
    goes line by line, whose errors name the line. Non-finite values ("nan") are read, and refused
    per frame by load()."""
    try:
        text = path.read_text(encoding="utf-8-sig")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # numpy warns of an empty file; the caller refuses it
            rows = np.loadtxt(io.StringIO(text), comments="#", ndmin=2, dtype=np.float64)
        lines = [n for n, line in enumerate(text.splitlines(), 1) if line.strip() and line.strip()[0] != "#"]
        if rows.shape[1:] == (8,) and len(rows) == len(lines):
            return rows[:, 0], rows[:, 1:], lines
    except (OSError, UnicodeDecodeError, ValueError):
        pass  # said line by line
    stamps, rest, lines = _tum_list(path, 8, "timestamp tx ty tz qx qy qz qw")
    try:
        gt = np.array(rest, dtype=np.float64).reshape(-1, 7)
    except ValueError:
        raise RecordingError("pose values must be numbers", path) from None
    return np.array([float(t) for t in stamps]), gt, lines


def _pose_sources(chosen, rgb_t, gt_t, max_gap: float, max_dt: float) -> dict[int, tuple[int, int, float]]:
    """Per rgb index, (i0, i1, a): the pose is trajectory row i0 slerped a of the way to row i1."""
    pose_src = {}
    for i in chosen:
        t = rgb_t[i]
        k = int(np.searchsorted(gt_t, t))
        if 0 < k < len(gt_t) and gt_t[k] - gt_t[k - 1] <= max_gap:
            span = gt_t[k] - gt_t[k - 1]
            pose_src[i] = (k - 1, k, 0.0 if span <= 0 else float((t - gt_t[k - 1]) / span))
        elif k < len(gt_t) and gt_t[k] == t:
            pose_src[i] = (k, k, 0.0)
        else:
            near = [j for j in (k - 1, k) if 0 <= j < len(gt_t)]
            j = min(near, key=lambda j: abs(gt_t[j] - t))
            if abs(gt_t[j] - t) <= max_dt:
                pose_src[i] = (j, j, 0.0)
    return pose_src


def _interpolated_pose(gt: np.ndarray, gt_lines: list[int], path: Path, i0: int, i1: int, a: float
                       ) -> Callable[[], np.ndarray]:
    """pose(): T (4, 4) between trajectory rows i0 and i1 (N, 7): linear translation, slerp rotation."""

    def pose() -> np.ndarray:
        T0, T1 = (quaternion_pose(gt[j], path, f"line {gt_lines[j]}") for j in (i0, i1))
        if i0 == i1:
            return T0
        T = np.eye(4)
        # Both quaternions are checked above; Slerp takes the shorter arc whichever sign they have.
        T[:3, :3] = Slerp([0.0, 1.0], Rotation.from_quat(gt[[i0, i1], 3:]))(a).as_matrix()
        T[:3, 3] = (1 - a) * T0[:3, 3] + a * T1[:3, 3]
        return T

    return pose


class _Trajectory:
    """Every frame's pose, interpolated at once on the first frame's ask: one slerp a frame took
    about 0.2 ms, so ``ltc check`` of a 100,000-frame recording spent 20 s on them. A frame whose
    rows are not poses (not finite, a quaternion not of unit length) gets :func:`_interpolated_pose`,
    whose FrameError names the line."""

    def __init__(self, gt: np.ndarray, gt_lines: list[int], path: Path, sources: list[tuple[int, int, float]]):
        self.gt, self.gt_lines, self.path = gt, gt_lines, path
        self.src = np.array(sources, dtype=np.float64).reshape(-1, 3)
        self.T_world_camera: np.ndarray | None = None  # (N, 4, 4)
        self.usable: np.ndarray | None = None  # (N,) bool
        self.lock = threading.Lock()  # the look-ahead's threads ask for poses too

    def _interpolate(self) -> None:
        i0, i1, a = self.src[:, 0].astype(np.intp), self.src[:, 1].astype(np.intp), self.src[:, 2]
        norm = np.linalg.norm(self.gt[:, 3:], axis=1)
        row_ok = np.isfinite(self.gt).all(axis=1) & (norm >= QUAT_NORM_RANGE[0]) & (norm <= QUAT_NORM_RANGE[1])
        self.usable = row_ok[i0] & row_ok[i1]
        i0, i1, a = i0[self.usable], i1[self.usable], a[self.usable]
        q = np.where(row_ok[:, None], self.gt[:, 3:], [0.0, 0.0, 0.0, 1.0])
        r0, r1 = Rotation.from_quat(q[i0]), Rotation.from_quat(q[i1])
        # Slerp between two rotations (scipy's Slerp, vectorised): r0 turned by a of the rotation
        # from r0 to r1, whose rotation vector scipy gives on the shorter arc.
        T = np.zeros((len(self.src), 4, 4))
        T[:, 3, 3] = 1.0
        if len(i0):
            R = (r0 * Rotation.from_rotvec((r0.inv() * r1).as_rotvec() * a[:, None])).as_matrix()
            # A frame on one row takes that row's rotation, exactly as quaternion_pose reads it.
            same = i0 == i1
            R[same] = Rotation.from_quat(q[i0[same]] / norm[i0[same], None]).as_matrix()
            T[self.usable, :3, :3] = R
            t = self.gt[:, :3]
            T[self.usable, :3, 3] = np.where(same[:, None], t[i0], (1 - a)[:, None] * t[i0] + a[:, None] * t[i1])
        self.T_world_camera = T

    def pose(self, n: int) -> Callable[[], np.ndarray]:
        def pose() -> np.ndarray:
            with self.lock:
                if self.T_world_camera is None:
                    self._interpolate()
            if not self.usable[n]:
                i0, i1, a = self.src[n]
                return _interpolated_pose(self.gt, self.gt_lines, self.path, int(i0), int(i1), float(a))()
            return self.T_world_camera[n].copy()
        return pose


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
    OPTIONS_SCHEMA = OPTIONS_SCHEMA

    def sniff(self, path) -> bool:
        try:
            p = Path(path)
            return (p / "rgb.txt").is_file() and (p / "depth.txt").is_file()
        except OSError:
            return False

    def open(self, path, options: dict | None = None) -> Recording:
        folder, opts = open_folder(path, options, OPTIONS_SCHEMA, self.name)
        depth_scale, max_dt = float(opts["depth_scale"]), float(opts["max_time_diff"])
        camera = opts["camera"]
        if camera is None:
            m = _TUM_FOLDER.search(folder.resolve().name)
            camera = f"fr{m.group(1)}" if m else "ros"
        poses_path = folder / opts["poses"]

        rgb_file, depth_file = folder / "rgb.txt", folder / "depth.txt"
        rgb_stamps, rgb_rest, _ = _tum_list(rgb_file, 2, "timestamp filename")
        depth_stamps, depth_rest, _ = _tum_list(depth_file, 2, "timestamp filename")
        if not poses_path.is_file():
            raise RecordingError(
                "TUM recording has no trajectory: ltc needs camera poses "
                "(groundtruth.txt, or a TUM-format file given with the reader option 'poses')",
                poses_path,
            )
        gt_t, gt, gt_lines = _trajectory(poses_path)
        if not rgb_stamps or not depth_stamps or not len(gt_t):
            empty = rgb_file if not rgb_stamps else depth_file if not depth_stamps else poses_path
            raise RecordingError("file lists no entries", empty)

        # Sort the trajectory by time (it normally is already) to bracket stamps by bisection.
        order = np.argsort(gt_t, kind="stable")
        gt_t, gt = gt_t[order], gt[order]
        gt_lines = [gt_lines[i] for i in order]

        rgb_t = np.array([float(s) for s in rgb_stamps])
        depth_t = np.array([float(s) for s in depth_stamps])
        chosen, d_idx = associate_nearest(rgb_t, depth_t, max_dt)
        pose_src = _pose_sources(chosen, rgb_t, gt_t, float(opts["max_pose_gap"]), max_dt)
        frames_idx = [i for i in chosen if i in pose_src]
        if not frames_idx:
            raise RecordingError(
                f"no rgb.txt entry has a depth image within {max_dt} s and a pose in {poses_path.name}",
                folder,
            )

        trajectory = _Trajectory(gt, gt_lines, poses_path, [pose_src[i] for i in frames_idx])
        intr_override = intrinsics_option(opts)
        width, height = first_size((folder / depth_rest[int(d_idx[i])][0] for i in frames_idx), folder)
        intr = make_intrinsics(width, height, TUM_CAMERAS[camera], intr_override)
        sources = (
            FrameSource(
                key=rgb_stamps[i],
                rgb_path=folder / rgb_rest[i][0],
                depth_path=folder / depth_rest[int(d_idx[i])][0],
                pose=trajectory.pose(n),
                extra={"timestamp": float(rgb_t[i]), "depth_timestamp": float(depth_t[d_idx[i]])},
            )
            for n, i in enumerate(frames_idx)
        )
        return Recording(
            path=str(folder),
            format="tum",
            identity=identity((p.name, read_bytes(p)) for p in (rgb_file, depth_file, poses_path)),
            intrinsics=intr,
            frames=frame_refs(sources, ImageFormat(intr, depth_scale)),
            up=up_option(opts, self.name),
            meta={
                "reader": self.name,
                "camera": camera if intr_override is None else "custom",
                "depth_scale": depth_scale,
                "poses_file": poses_path.name,
                "unassociated": len(rgb_stamps) - len(frames_idx),
            },
        )

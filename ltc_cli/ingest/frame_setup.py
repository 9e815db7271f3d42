"""Estimating a recording's up direction, for worlds that are not z-up (DESIGN.md section 2).

Two cues, both pure numpy:

1. The cameras' mean up axis. A hand-held or robot-mounted camera is mostly upright, so the camera's
   -y axis (OpenCV frame: y points down in the image) averaged over the trajectory is a first guess
   that is usually within a few tens of degrees of the true up.
2. The floor. Depth of a few frames, back-projected to the world, holds large horizontal planes
   (floor, table tops, seats). Planes whose normals agree (within PARALLEL_DEG) are one direction;
   the direction with the most support under which the cameras do not look upwards on average is
   the horizontal one, and its lowest plane with a large support is the floor, whose normal is the
   up direction, typically to a degree or two.

A hand-held camera looking down at a desk leans the first guess forward by its pitch: on
tum-fr1-rpy by 39-41 degrees, beyond the 30 degree cone this module once searched, so the desk
was missed and the map came out tilted by 22 degrees. The wall the camera faces then sits nearly
as close to the guess as the desk (90 degrees minus the pitch), so the cone alone cannot tell
them apart; the cameras' elevation can: under the wall's normal as "up" they would all look
steeply upwards, which hand-held and robot cameras do not.

``up_rotation`` turns the up direction into the rotation the map applies so that up becomes +z.
"""

from __future__ import annotations

from typing import NamedTuple, Sequence

import numpy as np

from ltc_cli.errors import RecordingError
from ltc_cli.geometry.camera import backproject, rotation_between, transform
from ltc_cli.geometry.depth_noise import estimate_depth_noise
from ltc_cli.geometry.pose_agreement import judge_poses
from ltc_cli.ingest.pose_check import frame_pairs, pose_message
from ltc_cli.ingest.sampling import sample_frames_of
from ltc_cli.types import Recording

# Planes whose normal is further than this from the cameras' guess are never floor: the guess leans
# by the cameras' mean pitch, which reaches 40 degrees for a camera looking down at a desk.
MAX_TILT_FROM_GUESS_DEG = 60.0
# Plane normals within this angle are one direction (a floor, a desk and a seat; a ramp of a few
# degrees stays with them, and its lowest plane decides).
PARALLEL_DEG = 10.0
# Under the true up the cameras' mean elevation (of their optical axes) is at most level; a
# candidate under which they look up by more than this on average is a wall.
MAX_MEAN_ELEVATION_DEG = 20.0
# Beyond the old 30 degree cone a direction must be borne by this share of the sampled points: a
# desk a camera is pitched down at fills much of its view (tum-fr1-rpy: 65 %), while planes that
# merely slice through walls and box faces do not (a room without a floor: 12 % at 50-58 degrees).
WIDE_CONE_DEG = 30.0
WIDE_MIN_SHARE = 0.2
# Point-to-plane distance (m) that counts as "on the plane": Kinect-class depth noise at 3-4 m is a
# few centimetres, so tighter thresholds split the floor into slivers.
INLIER_DISTANCE_M = 0.03
# Each frame's pose error tilts all of its points together: on tum-fr1-rpy the desk's normal fitted
# frame by frame scatters by 0.4-6.5 degrees, so one plane fitted to the pooled points of a few
# frames is off by one to three degrees depending on which frames were pooled (5 frames: 2.9, 16:
# 2.3, 20: 6.6). The support-weighted mean of the frames' own planes within REFINE_CONE_DEG of the
# pooled normal averages those errors out (12-32 frames: 0.5-1.0 degrees from the normal of the
# desk and floor fitted to 58 frames); the cone leaves out a ramp or a seat tilted by more, and a
# second pass re-centres it when the pooled normal was far off.
REFINE_CONE_DEG = 5.0
REFINE_PASSES = 2
# Frames sampled when a recording asks for its up axis to be estimated (else SAMPLE_FRAMES: the
# floor's height alone needs few).
UP_SAMPLE_FRAMES = 24
SAMPLE_FRAMES = 6  # even: exactly this many positions (sampling.sample_positions)
# The depth error is measured on at most this many of the sampled frames (about 15 ms each at 640).
NOISE_FRAMES = 6
# Depth readings outside this range are mostly noise (too near) or too sparse to hold a plane.
DEPTH_RANGE_M = (0.2, 6.0)


def _unit(v: np.ndarray) -> np.ndarray:
    n = float(np.linalg.norm(v))
    if not np.isfinite(n) or n < 1e-12:
        raise ValueError("cannot normalise a zero or non-finite vector")
    return v / n


def cameras_up(T_world_camera: np.ndarray) -> np.ndarray:
    """Mean up axis of the cameras: the mean of each camera's -y axis in world coordinates, (3,).

    T_world_camera: (N, 4, 4) or (4, 4) camera-to-world poses (OpenCV camera axes).
    """
    T = np.asarray(T_world_camera, dtype=np.float64).reshape(-1, 4, 4)
    if len(T) == 0:
        raise ValueError("no camera poses")
    ok = np.all(np.isfinite(T), axis=(1, 2))
    if not ok.any():
        raise ValueError("no finite camera poses")
    down = T[ok, :3, 1]  # camera y axis (image down) in world coordinates, (N, 3)
    mean_up = -down.mean(axis=0)
    if np.linalg.norm(mean_up) < 0.1:
        # Cameras rolled every which way cancel out; the first camera is as good a guess as any.
        mean_up = -down[0]
    return _unit(mean_up)


def _world_points(
    depth_samples: Sequence, intrinsics, max_points_per_frame: int, max_frames: int
) -> np.ndarray:
    """Back-project subsampled depth of up to ``max_frames`` frames to world points (P, 3)."""
    samples = list(depth_samples)
    if len(samples) > max_frames:
        # Evenly spread frames see more of the floor than consecutive ones.
        pick = np.linspace(0, len(samples) - 1, max_frames).round().astype(int)
        samples = [samples[i] for i in pick]
    intr_list = intrinsics if isinstance(intrinsics, (list, tuple)) else None
    chunks = []
    for i, sample in enumerate(samples):
        depth_m, T_world_camera = sample[0], np.asarray(sample[1], dtype=np.float64)
        intr = sample[2] if len(sample) > 2 else (intr_list[i] if intr_list else intrinsics)
        if intr is None:
            raise ValueError("depth samples need camera intrinsics")
        if not np.all(np.isfinite(T_world_camera)):
            continue
        depth_m = np.asarray(depth_m)
        h, w = depth_m.shape
        # A regular pixel grid (not random pixels) keeps the estimate deterministic and even.
        step = max(1, int(np.ceil(np.sqrt(h * w / max_points_per_frame))))
        v, u = np.mgrid[step // 2 : h : step, step // 2 : w : step]
        z = depth_m[v, u].astype(np.float64)
        keep = np.isfinite(z) & (z > DEPTH_RANGE_M[0]) & (z < DEPTH_RANGE_M[1])
        u, v, z = u[keep], v[keep], z[keep]
        x = z * (u - intr.cx) / intr.fx
        y = z * (v - intr.cy) / intr.fy
        p_cam = np.stack([x, y, z], axis=1)
        chunks.append(p_cam @ T_world_camera[:3, :3].T + T_world_camera[:3, 3])
    if not chunks:
        return np.zeros((0, 3))
    return np.concatenate(chunks, axis=0)


def _fit_plane(points: np.ndarray) -> tuple[np.ndarray, float]:
    """Least-squares plane n . p = d of points (P, 3): (n (3,), d)."""
    c = points.mean(axis=0)
    _, _, vt = np.linalg.svd(points - c, full_matrices=False)
    n = vt[2]
    return n, float(n @ c)


def _ransac_planes(
    points: np.ndarray,
    guess: np.ndarray,
    rng: np.random.Generator,
    max_planes: int,
    iterations: int,
    min_support: int,
    max_tilt_deg: float = MAX_TILT_FROM_GUESS_DEG,
) -> list[tuple[np.ndarray, float, int]]:
    """Sequential RANSAC for near-horizontal planes: [(n (3,) agreeing with guess, d, support)].

    Each round finds the best-supported plane whose normal is within ``max_tilt_deg`` of the
    guess, refits it by least squares, removes its inliers and looks again, so the floor and the
    table tops come out as separate planes.
    """
    cos_max = np.cos(np.radians(max_tilt_deg))
    planes = []
    remaining = points
    for _ in range(max_planes):
        if len(remaining) < max(3, min_support):
            break
        idx = rng.integers(0, len(remaining), size=(iterations, 3))
        a, b, c = remaining[idx[:, 0]], remaining[idx[:, 1]], remaining[idx[:, 2]]
        normals = np.cross(b - a, c - a)  # (I, 3)
        norms = np.linalg.norm(normals, axis=1)
        valid = norms > 1e-9
        normals[valid] /= norms[valid, None]
        # Orient every hypothesis along the guess so that "lowest" compares like with like.
        normals *= np.where(normals @ guess < 0, -1.0, 1.0)[:, None]
        valid &= normals @ guess >= cos_max
        if not valid.any():
            break
        normals, a = normals[valid], a[valid]
        offsets = np.einsum("ij,ij->i", normals, a)
        # (I, P) distances; I * P stays a few million floats with the caps of estimate_up.
        support = (np.abs(remaining @ normals.T - offsets) < INLIER_DISTANCE_M).sum(axis=0)
        best = int(np.argmax(support))
        if support[best] < min_support:
            break
        n, d = normals[best], offsets[best]
        for _refit in range(2):
            inliers = np.abs(remaining @ n - d) < INLIER_DISTANCE_M
            if inliers.sum() < 3:
                break
            n, d = _fit_plane(remaining[inliers])
            if n @ guess < 0:
                n, d = -n, -d
        inliers = np.abs(remaining @ n - d) < INLIER_DISTANCE_M
        if n @ guess >= cos_max and inliers.sum() >= min_support:
            planes.append((n, float(d), int(inliers.sum())))
        remaining = remaining[~inliers]
    return planes


def estimate_up(
    frames_T_world_camera: np.ndarray,
    depth_samples: Sequence | None = None,
    intrinsics=None,
    *,
    max_frames: int = 8,
    max_points_per_frame: int = 4000,
    seed: int = 0,
) -> np.ndarray:
    """The world's up direction, a unit vector (3,) in world coordinates.

    frames_T_world_camera: (N, 4, 4) camera-to-world poses; their mean -y axis is the first guess.
    depth_samples: optional list of ``(depth_m (H, W), T_world_camera (4, 4))`` (or triples with
        their own :class:`~ltc_cli.types.Intrinsics` third); when given, the guess is refined to the
        normal of the floor: the lowest well-supported plane of the horizontal direction
        (:func:`horizontal_planes`; beyond WIDE_CONE_DEG from the guess it must hold WIDE_MIN_SHARE
        of the points).
    intrinsics: the :class:`~ltc_cli.types.Intrinsics` of the depth samples (one for all, or a list
        aligned with them).

    Deterministic: RANSAC uses a generator seeded with ``seed`` and a fixed pixel grid. Returns the
    first guess when no plane is found (too little depth, or no horizontal surface in view).
    """
    guess = cameras_up(frames_T_world_camera)
    if not depth_samples:
        return guess
    points = _world_points(depth_samples, intrinsics, max_points_per_frame, max_frames)
    if len(points) < 100:
        return guess
    if len(points) > 20000:
        # Enough for a plane; keeps the (iterations x points) distance matrix small.
        points = points[np.random.default_rng(seed).choice(len(points), 20000, replace=False)]
    rng = np.random.default_rng(seed)
    # The floor rarely fills most of the view; 3 % of the points is a patch of a square metre or so
    # at Kinect range, while still rejecting stray bits of furniture.
    min_support = max(50, int(0.03 * len(points)))
    planes = _ransac_planes(points, guess, rng, max_planes=8, iterations=300, min_support=min_support)
    if not planes:
        return guess
    group = horizontal_planes(planes, frames_T_world_camera)
    if not group:
        return guess
    if float(group[0][0] @ guess) < np.cos(np.radians(WIDE_CONE_DEG)) and \
            sum(p[2] for p in group) < WIDE_MIN_SHARE * len(points):
        return guess
    # A plane counts as a floor candidate only with a fair share of the largest plane's support, so a
    # lone low step or rug edge does not win over the real floor.
    largest = max(s for _, _, s in group)
    candidates = [p for p in group if p[2] >= 0.25 * largest]
    # Lowest: the offset d = n . p of each plane along its own normal, all of them within
    # PARALLEL_DEG of one another.
    n, _, _ = min(candidates, key=lambda p: p[1])
    return refine_up(_unit(n), depth_samples, intrinsics, max_points_per_frame=max_points_per_frame, seed=seed)


def refine_up(up: np.ndarray, depth_samples: Sequence, intrinsics=None, *, max_points_per_frame: int = 4000,
              seed: int = 0, passes: int = REFINE_PASSES, cone_deg: float = REFINE_CONE_DEG) -> np.ndarray:
    """The support-weighted mean (3,) of each depth sample's best-supported plane whose normal lies
    within ``cone_deg`` of ``up`` (3,), repeated ``passes`` times around the new mean; ``up`` itself
    when no sample holds such a plane. Arguments as :func:`estimate_up`."""
    samples = list(depth_samples)
    intr_list = intrinsics if isinstance(intrinsics, (list, tuple)) else [intrinsics] * len(samples)
    clouds = [_world_points([sample], intr, max_points_per_frame, 1) for sample, intr in zip(samples, intr_list)]
    for _ in range(passes):
        total = np.zeros(3)
        for points in clouds:
            if len(points) < 100:
                continue
            # One generator per frame: a frame's plane does not depend on the frames before it.
            best = _ransac_planes(points, up, np.random.default_rng(seed), max_planes=1, iterations=200,
                                  min_support=max(50, int(0.03 * len(points))), max_tilt_deg=cone_deg)
            for n, _, support in best:
                total += support * n
        if not total.any():
            break
        up = _unit(total)
    return up


def mean_elevation_deg(T_world_camera: np.ndarray, up: np.ndarray) -> float:
    """The cameras' mean elevation (degrees, positive looking up) under the direction ``up`` (3,):
    the mean of arcsin(z . up) over their optical axes z, T_world_camera (N, 4, 4)."""
    z = np.asarray(T_world_camera, dtype=np.float64).reshape(-1, 4, 4)[:, :3, 2]
    z = z[np.all(np.isfinite(z), axis=1)]
    return float(np.degrees(np.arcsin(np.clip(z @ _unit(up), -1.0, 1.0))).mean()) if len(z) else 0.0


def horizontal_planes(planes: list, T_world_camera: np.ndarray) -> list:
    """The planes [(n (3,), d, support)] of the horizontal direction: planes grouped by normal
    (within PARALLEL_DEG of the group's best-supported plane), the group with the most support
    among those under whose normal the cameras look up by at most MAX_MEAN_ELEVATION_DEG on
    average; [] when every group fails that."""
    cos_par = np.cos(np.radians(PARALLEL_DEG))
    groups: list[list] = []
    for plane in sorted(planes, key=lambda p: -p[2]):
        for g in groups:
            if abs(float(plane[0] @ g[0][0])) >= cos_par:
                g.append(plane)
                break
        else:
            groups.append([plane])
    level = [g for g in groups if mean_elevation_deg(T_world_camera, g[0][0]) <= MAX_MEAN_ELEVATION_DEG]
    return max(level, key=lambda g: sum(p[2] for p in g)) if level else []


def estimate_up_from_frames(frames: Sequence, **kwargs) -> np.ndarray:
    """``estimate_up`` from loaded :class:`~ltc_cli.types.Frame` objects (poses, depth, intrinsics)."""
    frames = list(frames)
    if not frames:
        raise ValueError("no frames")
    T = np.stack([f.T_world_camera for f in frames])
    samples = [(f.depth_m, f.T_world_camera, f.intrinsics) for f in frames]
    return estimate_up(T, samples, **kwargs)


def up_rotation(up) -> np.ndarray:
    """R (3, 3) rotating the world's ``up`` (3,) onto +z: p_map = R @ p_world."""
    up = np.asarray(up, dtype=np.float64)
    if up.shape != (3,) or not np.all(np.isfinite(up)) or np.linalg.norm(up) < 1e-12:
        raise ValueError(f"up must be a finite non-zero 3-vector, got {up!r}")
    return rotation_between(up, np.array([0.0, 0.0, 1.0]))


__all__ = ["estimate_up", "estimate_up_from_frames", "refine_up", "cameras_up", "up_rotation"]


def estimate_floor_z(points_z: np.ndarray, band: float = 0.05, min_share: float = 0.03):
    """Height of the floor (map frame, z up) from the z (N,) of depth points of a few frames, or None.

    The floor is the lowest large horizontal surface: start from the 2nd percentile (below it lie
    only noise and reflections) and take the median of the points within ``band`` of it. When fewer
    than ``min_share`` of the points lie there, the floor was not in view: None.
    """
    z = np.asarray(points_z, dtype=np.float64)
    if z.size < 100:
        return None
    guess = float(np.percentile(z, 2))
    near = np.abs(z - guess) < band
    if near.mean() < min_share:
        return None
    return float(np.median(z[near]))


class FrameSetup(NamedTuple):
    """What a recording's sampled frames tell before its ingest."""

    R_up: np.ndarray  # (3, 3): turns the recording's world into the z-up map frame
    floor_z: float | None  # the floor's height in the map frame; None when no floor is in view
    depth_noise: float | None  # the sensor's depth error std at 1 m, measured; None when not


def frame_setup_for(rec: Recording, sample_frames: int | None = None, warn=None, on_poses=None) -> FrameSetup:
    """The up rotation, floor height and depth error of a recording (:class:`FrameSetup`).

    R_up turns the recording's world into the z-up map frame (given, or estimated from the
    cameras and the floor when ``up: estimate``); floor_z is the floor's height in the map frame,
    from the depth of a few frames (None when no floor is in view); depth_noise is measured on the
    same frames (ltc_cli/geometry/depth_noise.py). ``warn(message)`` is told when
    an estimate found no horizontal plane and rests on the cameras alone (a map tilted by the
    cameras' mean pitch is then likely), and when the poses do not fit the depth
    (ltc_cli/ingest/pose_check.py); ``on_poses(verdict)`` gets that check's PoseVerdict.
    """
    estimating = isinstance(rec.up, str) and rec.up == "estimate"
    if sample_frames is None:
        sample_frames = UP_SAMPLE_FRAMES if estimating else SAMPLE_FRAMES
    # In key order, so that the estimate is the same whichever way the reader lists the frames.
    frames = sorted(sample_frames_of(rec, sample_frames), key=lambda f: f.key)
    if rec.up is None:
        R_up = np.eye(3)
    elif estimating:
        if not frames:
            raise RecordingError("cannot estimate the up axis: no readable frame", rec.path)
        poses = np.array([f.T_world_camera for f in frames])
        up = estimate_up(poses, [(f.depth_m, f.T_world_camera) for f in frames], rec.intrinsics)
        R_up = rotation_between(up, [0.0, 0.0, 1.0])
        if warn is not None and np.allclose(up, cameras_up(poses)):
            warn(f"{rec.path}: no floor or table plane in the sampled frames: the up axis rests on the "
                 f"cameras' mean pose, which leans by their mean pitch; if the map looks tilted ('ltc info' "
                 f"shows the axis), give it (-r up=z, or up: in recording.yaml)")
    else:
        R_up = rotation_between(np.asarray(rec.up, dtype=np.float64), [0.0, 0.0, 1.0])
    if warn is not None or on_poses is not None:
        verdict = judge_poses(frame_pairs(rec, frames))
        if on_poses is not None:
            on_poses(verdict)
        if warn is not None and (message := pose_message(rec, verdict)):
            warn(message)
    zs = []
    for f in frames:
        v, u = np.mgrid[4 : f.depth_m.shape[0] : 8, 4 : f.depth_m.shape[1] : 8]
        z = f.depth_m[v, u]
        ok = z > 0
        pts = backproject(u[ok], v[ok], z[ok], f.intrinsics)
        zs.append(transform(f.T_world_camera, pts) @ R_up[2])
    floor_z = estimate_floor_z(np.concatenate(zs)) if zs else None
    # Evenly over the sampled frames (key order, so the same whichever way the reader lists them).
    step = max(1, -(-len(frames) // NOISE_FRAMES))
    depth_noise, _ = estimate_depth_noise([f.depth_m for f in frames[::step]])
    return FrameSetup(R_up, floor_z, depth_noise)

"""Slowly varying random processes along the robot's path: the localiser's pose error, and (used by
views.py) the per-object states that make a detector's misses and mislabels of one object persist
over nearby views."""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

CLIP_STD = 2.5  # the slow error never exceeds this many standard deviations
JITTER_CLIP_STD = 3.0


def smooth_noise(rng: np.random.Generator, n: int, length: float, dims: int = 1) -> np.ndarray:
    """(n, dims) Gaussian process over frame index with standard normal marginals and a Gaussian
    correlation of ``length`` frames: white noise convolved with a kernel normalised to unit
    energy (so each value's variance is exactly 1, whatever the length)."""
    k = max(1, int(math.ceil(3 * length)))
    x = np.arange(-k, k + 1, dtype=np.float64)
    w = np.exp(-0.5 * (x / length) ** 2)
    w /= math.sqrt(float(np.sum(w * w)))
    white = rng.standard_normal((n + 2 * k, dims))
    return np.stack([np.convolve(white[:, d], w, mode="valid") for d in range(dims)], axis=1)


def pose_errors(rng: np.random.Generator, n: int, opts: dict):
    """Position errors (n, 3) in metres and rotation errors (n, 3) (world-frame rotation vectors,
    radians) of a localiser along n frames: a slow drift (std pose_drift_m in x and y, a quarter of
    it in z; pose_drift_deg about z, a third of it about x and y; each clipped at CLIP_STD std)
    plus per-frame jitter (pose_jitter_m, pose_jitter_deg; clipped at JITTER_CLIP_STD std)."""
    slow = np.clip(smooth_noise(rng, n, opts["drift_frames"], 6), -CLIP_STD, CLIP_STD)
    fast = np.clip(rng.standard_normal((n, 6)), -JITTER_CLIP_STD, JITTER_CLIP_STD)
    shape = np.array([1.0, 1.0, 0.25])
    tilt = np.array([1 / 3, 1 / 3, 1.0])
    d_pos = slow[:, :3] * shape * opts["pose_drift_m"] + fast[:, :3] * shape * opts["pose_jitter_m"]
    d_rot = np.radians(slow[:, 3:] * tilt * opts["pose_drift_deg"] + fast[:, 3:] * tilt * opts["pose_jitter_deg"])
    return d_pos, d_rot


def estimated_poses(T_world_camera: np.ndarray, rng: np.random.Generator, opts: dict) -> np.ndarray:
    """What a localiser reports for the true poses (F, 4, 4): each moved by :func:`pose_errors`
    (the rotation error turns the camera about its own centre). The true poses when every pose
    option is 0."""
    if not any(opts[k] > 0 for k in ("pose_drift_m", "pose_drift_deg", "pose_jitter_m", "pose_jitter_deg")):
        return T_world_camera
    d_pos, d_rot = pose_errors(rng, len(T_world_camera), opts)
    out = T_world_camera.copy()
    out[:, :3, :3] = (Rotation.from_rotvec(d_rot) * Rotation.from_matrix(T_world_camera[:, :3, :3])).as_matrix()
    out[:, :3, 3] += d_pos
    return out

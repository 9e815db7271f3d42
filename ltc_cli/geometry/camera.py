"""Cameras and poses: pinhole projection (eq. 1), rigid transforms, quaternions via scipy.

Poses are ``T_world_camera`` (camera-to-world, 4x4); the camera frame is OpenCV (x right, y down,
z forward).
"""

from __future__ import annotations

import numpy as np


def quat_to_rot(q_xyzw) -> np.ndarray:
    """Rotation matrix (3, 3) of a unit quaternion given as (qx, qy, qz, qw)."""
    x, y, z, w = (float(v) for v in q_xyzw)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def pose_matrix(t_xyz, q_xyzw) -> np.ndarray:
    """T (4, 4) from a translation and a unit quaternion (qx, qy, qz, qw)."""
    T = np.eye(4)
    T[:3, :3] = quat_to_rot(q_xyzw)
    T[:3, 3] = np.asarray(t_xyz, dtype=np.float64)
    return T


def is_rotation(R: np.ndarray, tol: float = 1e-3) -> bool:
    """True when R (3, 3) is orthonormal with determinant +1 (within tol)."""
    R = np.asarray(R, dtype=np.float64)
    if R.shape != (3, 3) or not np.all(np.isfinite(R)):
        return False
    return bool(np.abs(R.T @ R - np.eye(3)).max() < tol and abs(np.linalg.det(R) - 1.0) < tol)


def invert_pose(T: np.ndarray) -> np.ndarray:
    """Inverse of a rigid transform (4, 4)."""
    Ti = np.eye(4)
    R = T[:3, :3]
    Ti[:3, :3] = R.T
    Ti[:3, 3] = -R.T @ T[:3, 3]
    return Ti


def rotation_between(a, b) -> np.ndarray:
    """Smallest rotation R (3, 3) with R a = b for unit-norm directions a, b (3,)."""
    a = np.asarray(a, dtype=np.float64) / np.linalg.norm(a)
    b = np.asarray(b, dtype=np.float64) / np.linalg.norm(b)
    v = np.cross(a, b)
    c = float(a @ b)
    if c < -1 + 1e-9:  # opposite: half turn about any axis normal to a
        axis = np.cross(a, [1.0, 0, 0])
        if np.linalg.norm(axis) < 1e-6:
            axis = np.cross(a, [0, 1.0, 0])
        axis /= np.linalg.norm(axis)
        return 2 * np.outer(axis, axis) - np.eye(3)
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx / (1 + c)


def backproject(u, v, z, intr) -> np.ndarray:
    """Pixels to camera-frame points (N, 3) by eq. 1: X = Z (u - cx) / fx, Y = Z (v - cy) / fy."""
    z = np.asarray(z, dtype=np.float64)
    x = z * (np.asarray(u, dtype=np.float64) - intr.cx) / intr.fx
    y = z * (np.asarray(v, dtype=np.float64) - intr.cy) / intr.fy
    return np.stack([x, y, z], axis=-1)


def transform(T: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply T (4, 4) to points (..., 3)."""
    return points @ T[:3, :3].T + T[:3, 3]


def project(points_cam: np.ndarray, intr):
    """Camera-frame points (..., 3) to pixels: (u (...), v (...), z (...))."""
    z = points_cam[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = intr.fx * points_cam[..., 0] / z + intr.cx
        v = intr.fy * points_cam[..., 1] / z + intr.cy
    return u, v, z

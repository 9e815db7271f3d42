"""Cameras and poses: pinhole projection (eq. 1), rigid transforms, quaternions via scipy.

Poses are ``T_world_camera`` (camera-to-world, 4x4); the camera frame is OpenCV (x right, y down,
z forward).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation


def quat_to_rot(q_xyzw) -> np.ndarray:
    """Rotation matrix (3, 3) of a unit quaternion given as (qx, qy, qz, qw) (scipy's order)."""
    return Rotation.from_quat(np.asarray(q_xyzw, dtype=np.float64)).as_matrix()


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
    """Smallest rotation R (3, 3) with R a = b for directions a, b (3,) (normalised here).

    For opposite directions every half turn about an axis normal to a is smallest; the one about
    a x (1, 0, 0) (or a x (0, 1, 0) when a is along x) is returned, so a given up direction always
    gives the same map frame.
    """
    a = np.asarray(a, dtype=np.float64) / np.linalg.norm(a)
    b = np.asarray(b, dtype=np.float64) / np.linalg.norm(b)
    if float(a @ b) < -1 + 1e-9:
        axis = np.cross(a, [1.0, 0.0, 0.0])
        if np.linalg.norm(axis) < 1e-6:
            axis = np.cross(a, [0.0, 1.0, 0.0])
        return Rotation.from_rotvec(np.pi * axis / np.linalg.norm(axis)).as_matrix()
    # align_vectors(targets, sources) rotates sources onto targets; one pair: the shortest rotation.
    R, _ = Rotation.align_vectors(b[None], a[None])
    return R.as_matrix()


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

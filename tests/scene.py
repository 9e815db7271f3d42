"""A tiny analytic scene for unit tests, independent of ltc's own ray casting.

The camera looks along world +x from (0, 0, cam_z), z up, so for an axis-aligned box the visible
front face is the rectangle at x = x_front, and its image is a rectangle of constant depth
x_front: pixel u = cx + fx * (-y) / Z, v = cy + fy * (cam_z - z) / Z.
"""

import numpy as np

from ltc_cli.types import Intrinsics

INTR = Intrinsics(640, 480, 500.0, 500.0, 319.5, 239.5)
CAM_Z = 1.0


def T_world_camera(cam_x=0.0, cam_y=0.0, cam_z=CAM_Z):
    T = np.eye(4)
    # Columns: the camera's x (right), y (down), z (forward) axes in the world.
    T[:3, :3] = np.array([[0, 0, 1], [-1, 0, 0], [0, -1, 0]], dtype=float)
    T[:3, 3] = [cam_x, cam_y, cam_z]
    return T


def face_rect(y0, y1, z0, z1, depth, intr=INTR, cam_y=0.0, cam_z=CAM_Z):
    """Pixel rectangle (u0, u1, v0, v1), half-open, of a fronto-parallel face at camera depth."""
    u_a = intr.cx + intr.fx * (-(y1 - cam_y)) / depth
    u_b = intr.cx + intr.fx * (-(y0 - cam_y)) / depth
    v_a = intr.cy + intr.fy * (cam_z - z1) / depth
    v_b = intr.cy + intr.fy * (cam_z - z0) / depth
    u0, u1 = int(np.ceil(u_a - 0.5)), int(np.floor(u_b - 0.5)) + 1
    v0, v1 = int(np.ceil(v_a - 0.5)), int(np.floor(v_b - 0.5)) + 1
    return max(u0, 0), min(u1, intr.width), max(v0, 0), min(v1, intr.height)


def render(boxes, wall_x=4.0, intr=INTR, cam_y=0.0):
    """Depth (H, W) of a wall at x = wall_x and axis-aligned boxes given as
    (x0, x1, y0, y1, z0, z1); returns depth and a list of per-box visible masks."""
    depth = np.full((intr.height, intr.width), wall_x, dtype=np.float32)
    owner = np.full(depth.shape, -1)
    for i, (x0, x1, y0, y1, z0, z1) in sorted(enumerate(boxes), key=lambda t: -t[1][0]):
        u0, u1, v0, v1 = face_rect(y0, y1, z0, z1, x0, intr, cam_y=cam_y)
        if u1 <= u0 or v1 <= v0:
            continue
        region = depth[v0:v1, u0:u1]
        nearer = x0 < region
        region[nearer] = x0
        owner[v0:v1, u0:u1][nearer] = i
    return depth, [owner == i for i in range(len(boxes))]

"""Free-space carving of a map object's box: a side that the frame's depth sees through moves in.

Pure numpy. Issue 9: "a box never extends through space the depth showed empty". Integration
grows a partial object's box by enclosing each view (DESIGN.md 1.3), and each view's box carries
its mask's bleed and the localiser's drift: a chair's box grew 0.4 m behind the chair into the
empty aisle. When a frame detects the object, the rays of that frame that pass through a slice
along one side of its box and end well beyond it show the slice empty, and the side moves in. Only
what lies beyond the frame's own detection is carved (that box is what this frame sees of the
object), and only a slice empty at every height: a chair's box is mostly air between its legs and
above its seat, but no slice of its footprint is air from the floor to its top.
"""

from __future__ import annotations

import numpy as np

from ltc_cli.geometry.boxes import Box, box_corners, rot_z
from ltc_cli.geometry.camera import project, transform

# The sides of a box's footprint: (axis, sign) in the box's own frame.
SIDES = ((0, 1.0), (0, -1.0), (1, 1.0), (1, -1.0))
# A slice is sampled on a grid across the side and up its height.
GRID = (6, 6)
# A slice is empty when this share of its sample points with a depth reading are seen through (a
# point hidden behind something nearer counts against: the slice must be seen empty, not unseen) ...
FREE_SHARE = 0.9
# ... and at least this share of them have a reading (the rest out of the image or without one).
READ_SHARE = 0.5


def slice_points(center: np.ndarray, yaw: float, size: np.ndarray, axis: int, sign: float, thickness: float,
                 grid: tuple[int, int] = GRID) -> np.ndarray:
    """(grid[0] * grid[1], 3) map-frame points on the mid-plane of the slice ``thickness`` metres
    thick along side (``axis``, ``sign``) of a box (centre (3,), yaw, size (3,)): a grid across the
    side and up its height, each point in the middle of its cell."""
    other = 1 - axis
    across = ((np.arange(grid[0]) + 0.5) / grid[0] - 0.5) * size[other]
    up = ((np.arange(grid[1]) + 0.5) / grid[1] - 0.5) * size[2]
    a, h = np.meshgrid(across, up, indexing="ij")
    local = np.zeros((a.size, 3))
    local[:, axis] = sign * (size[axis] - thickness) / 2
    local[:, other] = a.ravel()
    local[:, 2] = h.ravel()
    return center + local @ rot_z(yaw).T


def grid_pixel(coord: np.ndarray, ray_step: int, length: int) -> np.ndarray:
    """The pixel index (int array) that stage 4 reads for the ``ray_step`` block holding each pixel
    coordinate ``coord`` (u or v, in an image ``length`` pixels wide or high;
    :func:`~ltc_cli.pipeline.visibility.ray_grid`: one ray per block, at its centre, read at
    ``int`` of it; a last block too short for a centre belongs to the one before)."""
    first = ray_step / 2 - 0.5
    last = int(np.ceil((length - first) / ray_step)) - 1
    block = np.clip(np.floor((np.asarray(coord) + 0.5) / ray_step), 0, last)
    return (first + block * ray_step).astype(int)


def seen_through(points_xyz: np.ndarray, T_camera_map: np.ndarray, depth_m: np.ndarray, intr,
                 tolerance: float, ray_step: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """(free (N,), read (N,)) for map-frame points seen by a camera: read where the point projects
    into the image, in front of the camera, onto a depth reading; free where that reading lies more
    than ``tolerance`` metres beyond the point (the ray passed through it). The reading is the one
    of the point's ``ray_step`` block that stage 4 reads (:func:`grid_pixel`), so a Dask worker's
    sparse depth gives the same answer."""
    u, v, z = project(transform(T_camera_map, points_xyz), intr)
    h, w = depth_m.shape
    inside = (z > 1e-6) & (u > -0.5) & (u < w - 0.5) & (v > -0.5) & (v < h - 0.5)
    cols, rows = grid_pixel(u[inside], ray_step, w), grid_pixel(v[inside], ray_step, h)
    d = np.zeros(len(z))
    d[inside] = depth_m[rows, cols]
    read = inside & (d > 0)
    return read & (d > z + tolerance), read


def _center_of(box: Box, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The centre (3,) of ``box`` cut to footprint [lo, hi] (2,) in its own frame."""
    return np.array([*(box.center[:2] + rot_z(box.yaw)[:2, :2] @ ((lo + hi) / 2)), box.center[2]])


def carve_box(box: Box, keep: Box, T_camera_map: np.ndarray, depth_m: np.ndarray, intr, step: float,
              max_share: float, tolerance: float, ray_step: int = 1) -> Box:
    """``box`` with each side of its footprint moved in ``step`` metres at a time while the slice it
    gives up is empty in this frame (:func:`seen_through`: FREE_SHARE of the slice's sample points
    with a reading free, READ_SHARE of them with one), never past the footprint of ``keep`` (the
    frame's detection, taken in the box's axes) and by at most ``max_share`` of the side's length.

    box, keep: map frame; T_camera_map (4, 4); depth_m (H, W) metres, 0 = no reading; ray_step:
    the depth is read at stage 4's rays (:func:`seen_through`). The height, yaw, visible flags and
    Defined flag stay (``box`` itself when nothing is carved)."""
    half = box.size[:2] / 2
    lo, hi = -half.copy(), half.copy()
    local = (box_corners(keep.center, keep.yaw, keep.size)[:4, :2] - box.center[:2]) @ rot_z(box.yaw)[:2, :2]
    keep_lo, keep_hi = local.min(axis=0), local.max(axis=0)
    for axis, sign in SIDES:
        budget = max_share * box.size[axis]
        while budget >= step - 1e-9:
            # The side's position and the detection's along it, both measured outwards.
            face, inner = (hi[axis], keep_hi[axis]) if sign > 0 else (-lo[axis], -keep_lo[axis])
            if face - step < inner - 1e-9:
                break
            size = np.array([hi[0] - lo[0], hi[1] - lo[1], box.size[2]])
            pts = slice_points(_center_of(box, lo, hi), box.yaw, size, axis, sign, step)
            free, read = seen_through(pts, T_camera_map, depth_m, intr, tolerance, ray_step)
            if read.sum() < READ_SHARE * len(pts) or free.sum() < FREE_SHARE * read.sum():
                break
            if sign > 0:
                hi[axis] -= step
            else:
                lo[axis] += step
            budget -= step
    if np.array_equal(lo, -half) and np.array_equal(hi, half):
        return box
    return Box(_center_of(box, lo, hi), box.yaw, np.array([hi[0] - lo[0], hi[1] - lo[1], box.size[2]]),
               box.visible.copy(), box.defined)

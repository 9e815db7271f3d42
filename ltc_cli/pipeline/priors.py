"""Stage 1's priors for one-view boxes, ltc's additions to the paper's modeling: the far side a
single view cannot measure, the typical depth of a slab seen from the front, and the floor under
furniture whose bottom was not seen. Pure numpy over boxes; modeling.py applies them."""

from __future__ import annotations

import numpy as np

from ltc_cli.geometry.boxes import CORNER_SIGNS, Boxes


def unobserved_far_side(boxes: Boxes, cam_xyz: np.ndarray, thin_extent: float) -> np.ndarray:
    """(M, 8) vertices whose position a single view cannot have measured.

    One view of a cabinet or a fridge sees only its front: the points span no depth, so the box is a
    slab padded to the minimum extent and its far vertices are guesses that the Z-buffer test cannot
    catch (the observed front is nearer than them by less than the tolerance). Along a horizontal
    box axis thinner than ``thin_extent``, the 4 vertices on the side away from the camera are
    therefore not visible, and the box is not Defined until another view measures that side.
    """
    out = np.zeros((len(boxes), 8), dtype=bool)
    rel = cam_xyz[:2] - boxes.center[:, :2]  # (M, 2) towards the camera
    c, s = np.cos(boxes.yaw), np.sin(boxes.yaw)
    toward = (c * rel[:, 0] + s * rel[:, 1], -s * rel[:, 0] + c * rel[:, 1])  # in the box frame
    for axis in (0, 1):
        thin = boxes.size[:, axis] < thin_extent
        far_sign = -np.sign(toward[axis])  # the side away from the camera
        out |= thin[:, None] & (CORNER_SIGNS[None, :, axis] == far_sign[:, None])
    return out


def background_gap(depth_m: np.ndarray, rows: tuple, cols: tuple, z_obj: float, band: int = 8) -> float:
    """How far behind the object (metres along the view) the nearest background is: the median
    depth on the top and sides of the mask's bounding box (rows, cols: first and last) grown by
    ``band`` px, minus the object's median depth; inf when nothing is seen there."""
    h, w = depth_m.shape
    r0, r1 = max(rows[0] - band, 0), min(rows[1] + band, h - 1)
    c0, c1 = max(cols[0] - band, 0), min(cols[1] + band, w - 1)
    ring = np.concatenate([depth_m[r0, c0 : c1 + 1], depth_m[r0 : r1 + 1, c0], depth_m[r0 : r1 + 1, c1]])
    ring = ring[ring > 0]
    return float(np.median(ring)) - z_obj if ring.size else np.inf


def deepen_slabs(boxes: Boxes, depth_prior: np.ndarray, gap: np.ndarray, cam_xyz: np.ndarray,
                 thin_extent: float) -> None:
    """Give one-view slabs (in place) the typical depth of their class, away from the camera.

    A fridge or an oven against a wall is only ever seen from the front, so no view measures its
    depth. Along a horizontal axis thinner than ``thin_extent`` the box grows away from the camera
    to ``depth_prior`` (NaN: no prior), but never past the background seen around the object
    (``gap`` metres behind it: the wall). The grown side stays not visible (see
    :func:`unobserved_far_side`).
    """
    rel = cam_xyz[:2] - boxes.center[:, :2]
    c, s = np.cos(boxes.yaw), np.sin(boxes.yaw)
    toward = (c * rel[:, 0] + s * rel[:, 1], -s * rel[:, 0] + c * rel[:, 1])
    axes = (np.stack([c, s], -1), np.stack([-s, c], -1))
    for axis in (0, 1):
        size = boxes.size[:, axis]
        target = np.minimum(depth_prior, size + np.maximum(gap - 0.02, 0.0))
        grow = np.where((size < thin_extent) & np.isfinite(target) & (target > size), target - size, 0.0)
        if grow.any():
            away = -np.sign(toward[axis])[:, None] * axes[axis]  # (M, 2) unit, away from the camera
            boxes.center[:, :2] += away * (grow / 2)[:, None]
            boxes.size[:, axis] += grow
            boxes._corners = None


def ground_to_floor(boxes: Boxes, grounded: np.ndarray, floor_z: float, max_gap: float) -> None:
    """Extend boxes (in place) of furniture that stands on the floor down to it, when their bottom
    was not seen.

    A chair behind a table shows only its back above the table top; its box would be a 0.4 m slab
    in mid-air. Furniture of these classes stands on the floor, so a box whose bottom is above the
    floor by less than ``max_gap`` missed its lower part (hidden, or left out of the mask; the
    Z-buffer cannot tell when the occluder is close in front), and its bottom is the floor. The
    bottom vertices are then not visible (inferred, not observed), so the box is not Defined by
    this.
    """
    zmin = boxes.center[:, 2] - boxes.size[:, 2] / 2
    zmax = boxes.center[:, 2] + boxes.size[:, 2] / 2
    gap = zmin - floor_z
    extend = grounded & (gap > 0.02) & (gap < max_gap)
    if extend.any():
        boxes.center[extend, 2] = (floor_z + zmax[extend]) / 2
        boxes.size[extend, 2] = zmax[extend] - floor_z
        # A bottom within 10 cm of the floor was seen, short of the thinned band and the noise.
        boxes.visible[extend & (gap > 0.1), :4] = False
        boxes._corners = None

"""Pictures on walls: detections that are flat on the wall around them are not objects.

A detector takes a poster or a painting for a tv (or a screen for a picture of one) from every view
of it, so the confirmation rules cannot tell it from furniture. Depth can: the pixels of a picture
lie on the same vertical plane as the wall around it, while a tv, a cabinet or a plant stands out
from what is behind it. Pure numpy; stage 1 (frame_modeling.py) drops such detections.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from ltc_cli.types import Intrinsics


def _points_map(v: np.ndarray, u: np.ndarray, depth_m: np.ndarray, intr: Intrinsics, T_map_camera: np.ndarray):
    """Map-frame points (N, 3) of pixels (v, u) with a depth reading."""
    z = depth_m[v, u]
    ok = z > 0
    z, u, v = z[ok], u[ok], v[ok]
    cam = np.stack([(u - intr.cx) * z / intr.fx, (v - intr.cy) * z / intr.fy, z], axis=-1)
    return cam @ T_map_camera[:3, :3].T + T_map_camera[:3, 3]


def flat_on_wall(mask: np.ndarray, depth_m: np.ndarray, intr: Intrinsics, T_map_camera: np.ndarray,
                 tolerance: float, band_px: int = 10, gap_px: int = 3, max_tilt: float = 0.3,
                 min_points: int = 40) -> bool:
    """True when the detection (mask (H, W) bool) lies flat on a wall: the pixels in a band around
    the mask (``gap_px`` to ``gap_px + band_px`` pixels out, past where masks bleed) fit one plane,
    that plane is vertical (|normal z| <= ``max_tilt``; map z is up), 80 % of the band lies within
    ``tolerance`` of it, and the mask's own pixels lie within ``tolerance`` of it (median distance;
    fewer than half of them standing out towards the camera).

    A picture lying on a table (a book, a keyboard) is on a horizontal surface and never counts:
    only walls hang pictures that detectors mistake for screens.
    """
    vs, us = np.nonzero(mask)
    if vs.size == 0:
        return False
    h, w = mask.shape
    pad = gap_px + band_px
    v0, v1 = max(0, vs.min() - pad), min(h, vs.max() + pad + 1)
    u0, u1 = max(0, us.min() - pad), min(w, us.max() + pad + 1)
    crop = mask[v0:v1, u0:u1]
    near = ndimage.binary_dilation(crop, iterations=gap_px)
    band = ndimage.binary_dilation(near, iterations=band_px) & ~near
    bv, bu = np.nonzero(band)
    ring = _points_map(bv + v0, bu + u0, depth_m, intr, T_map_camera)
    inside = _points_map(vs, us, depth_m, intr, T_map_camera)
    if len(ring) < min_points or len(inside) < min_points:
        return False
    centre = np.median(ring, axis=0)
    _, _, vt = np.linalg.svd(ring - centre, full_matrices=False)
    normal = vt[-1]
    if abs(normal[2]) > max_tilt:
        return False  # not a wall
    if np.mean(np.abs((ring - centre) @ normal) <= tolerance) < 0.8:
        return False  # the surroundings are not one surface (a thing in front of several)
    d = (inside - centre) @ normal
    # Oriented towards the camera: a thing in front of the wall has all its points on that side.
    cam = T_map_camera[:3, 3]
    if (cam - centre) @ normal < 0:
        d = -d
    return bool(np.median(np.abs(d)) <= tolerance and np.mean(d > tolerance) < 0.5)

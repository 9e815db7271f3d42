"""Pictures on walls: detections that are flat on the wall around them are not objects.

A detector takes a poster or a painting for a tv (or a screen for a picture of one) from every view
of it, so the confirmation rules cannot tell it from furniture. Depth can: the pixels of a picture
lie on the same vertical plane as the wall around it, while a tv, a cabinet or a plant stands out
from what is behind it. Pure numpy; stage 1 (frame_modeling.py) drops such detections, and the
mapper counts them on the objects they fall in (:func:`picture_hits`): an object made from a
poster's other views goes when enough of its detections were flat (:func:`is_picture`).
"""

from __future__ import annotations

import cv2
import numpy as np

from ltc_cli.geometry.boxes import Boxes, rot_z
from ltc_cli.types import Intrinsics

#: Metres a flat detection's point may lie outside the box of the object it counts on: the point is
#: on the wall, and a poster's box, made from its views that were not judged flat, stands off it.
PICTURE_MARGIN = 0.1
#: The band around a mask whose depth is the wall: from GAP_PX to GAP_PX + BAND_PX pixels out of a
#: 640 x 480 image (past where masks bleed), scaled up with a larger image (modeling.scale_pixels).
BAND_PX = 10
GAP_PX = 3


def _points_map(v: np.ndarray, u: np.ndarray, depth_m: np.ndarray, intr: Intrinsics, T_map_camera: np.ndarray):
    """Map-frame points (N, 3) of pixels (v, u) with a depth reading."""
    z = depth_m[v, u]
    ok = z > 0
    z, u, v = z[ok], u[ok], v[ok]
    cam = np.stack([(u - intr.cx) * z / intr.fx, (v - intr.cy) * z / intr.fy, z], axis=-1)
    return cam @ T_map_camera[:3, :3].T + T_map_camera[:3, 3]


def square_dilation(mask: np.ndarray, radius: int) -> np.ndarray:
    """(H, W) bool: pixels within ``radius`` (a (2r+1)-square) of the mask; nothing outside the
    image counts. ndimage.maximum_filter(mask, 2r + 1, mode="constant"), by OpenCV: an ingest
    does not import scipy.ndimage (tests/test_accuracy_rules.py checks the two agree)."""
    kernel = np.ones((2 * radius + 1, 2 * radius + 1), np.uint8)
    out = cv2.dilate(np.ascontiguousarray(mask).view(np.uint8), kernel, borderType=cv2.BORDER_CONSTANT, borderValue=0)
    return out.view(bool)


def wall_planes(points_xyz: np.ndarray, depth: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Candidate walls [(centre (3,), unit normal (3,))] behind a band of points_xyz (N, 3) that is
    partly off its wall, each a least-squares plane (SVD about the median): of the band's farther
    half (``depth`` (N,): each point's camera depth), and of the half nearest to the plane of all
    the points, twice over.

    A wall is the farthest thing there is, so what the band around a poster meets off the wall (a
    sideboard's top or front below it) stands in front of it, and a plane fitted to every point
    tilts between the two. The farther half misses the wall when the band's off-wall part is the
    larger one; the trimmed fit then still finds it from the wall's own points."""
    planes = [plane_fit(points_xyz[np.asarray(depth) >= median(depth)])]
    pts = points_xyz
    for _ in range(2):
        centre, normal = plane_fit(pts)
        dist = np.abs((points_xyz - centre) @ normal)
        pts = points_xyz[dist <= median(dist)]
    return planes + [plane_fit(pts)]


def median(values: np.ndarray) -> np.ndarray:
    """np.median(values, axis=0) of finite values (N,) or (N, K) (N >= 1), to the same bits.

    The test runs a dozen medians of a few hundred values per detection, where np.median's generic
    checks cost more than the partition itself (about half of the test's time on tum-fr1-rpy)."""
    n = len(values)
    k = n // 2
    if n % 2:
        return np.partition(values, k, axis=0)[k]
    part = np.partition(values, (k - 1, k), axis=0)
    return (part[k - 1] + part[k]) / 2


def plane_fit(points_xyz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(centre (3,), unit normal (3,)): the least-squares plane of points_xyz (N, 3) through their
    median (SVD: the direction of least spread)."""
    centre = median(points_xyz)
    return centre, np.linalg.svd(points_xyz - centre, full_matrices=False)[2][-1]


def on_wall(band_xyz: np.ndarray, centre: np.ndarray, normal: np.ndarray, tolerance: float, share: float,
            max_tilt: float, camera_xyz: np.ndarray | None = None, min_facing: float = 0.0,
            max_behind: float = 0.1) -> bool:
    """Whether ``share`` of the band's points (band_xyz (N, 3)) lie within ``tolerance`` of the
    plane (centre, normal) and that plane is vertical (|normal z| <= ``max_tilt``).

    With ``camera_xyz`` (the band partly off the plane), also: the camera faces the plane (the
    cosine between its normal and the ray at least ``min_facing``: a plane along the line of sight,
    a table's edge running away, leaves depth unmeasured), and at most ``max_behind`` of the band
    lies beyond it: what the band meets off a wall stands in front of it, while a screen's bezel is
    a plane with the room behind it."""
    if abs(normal[2]) > max_tilt:
        return False
    d = (band_xyz - centre) @ normal
    if camera_xyz is not None:
        ray = centre - camera_xyz
        if abs(ray @ normal) < min_facing * np.linalg.norm(ray):
            return False
        if np.mean((-d if ray @ normal < 0 else d) > tolerance) > max_behind:
            return False
    return bool(np.mean(np.abs(d) <= tolerance) >= share)


def flat_on_wall(mask: np.ndarray, depth_m: np.ndarray, intr: Intrinsics, T_map_camera: np.ndarray,
                 tolerance: float, band_px: int = BAND_PX, gap_px: int = GAP_PX, max_tilt: float = 0.3,
                 min_points: int = 40, step: int = 3, noise_per_m2: float = 0.0, wall_share: float | None = None,
                 min_facing: float = 0.7) -> bool:
    """True when the detection (mask (H, W) bool) lies flat on a wall: the pixels in a band around
    the mask (``gap_px`` to ``gap_px + band_px`` pixels out, past where masks bleed) fit one plane,
    that plane is vertical (|normal z| <= ``max_tilt``; map z is up), 80 % of the band lies within
    ``tolerance + noise_per_m2 * Z^2`` of it (Z: the band's median depth), and the mask's own pixels
    lie on it: their median signed distance is within ``tolerance``. With ``wall_share``, a band
    partly off its wall (a sideboard below a poster) also finds it: ``wall_share`` of the band on
    one of :func:`wall_planes`, which the camera faces (cosine at least ``min_facing``) and beyond
    which it sees next to nothing (:func:`on_wall`).

    A depth sensor's noise grows with the square of the depth (Kinect v1: sigma about 0.0019 Z^2,
    Nguyen et al., 3DIMPVT 2012): at 3 m a fixed 2.5 cm band holds well under 80 % of a plain wall.
    The median of the mask's hundreds of distances is nearly free of that noise, so the test of
    how far the detection stands out keeps the fixed tolerance: a tv 5 cm proud of the wall stays.
    With ``noise_per_m2`` 0 (the setting's null) the earlier inside test stays: median distance
    within ``tolerance`` and fewer than half of the pixels standing out towards the camera.

    A picture lying on a table (a book, a keyboard) is on a horizontal surface and never counts:
    only walls hang pictures that detectors mistake for screens.
    """
    # On a grid of every ``step``-th pixel: the test needs a few hundred points, not every pixel,
    # and a square maximum filter is the cheapest dilation.
    h, w = mask.shape
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    if rows.size == 0:
        return False
    pad = gap_px + band_px
    v0, v1 = max(0, rows[0] - pad), min(h, rows[-1] + pad + 1)
    u0, u1 = max(0, cols[0] - pad), min(w, cols[-1] + pad + 1)
    # A few thousand grid cells whatever the mask's size.
    step = max(step, int(np.ceil(np.sqrt((v1 - v0) * (u1 - u0) / 4000.0))))
    crop = mask[v0:v1:step, u0:u1:step]
    gap, reach = -(-gap_px // step), -(-(gap_px + band_px) // step)
    near = square_dilation(crop, gap)
    band = square_dilation(crop, reach) & ~near
    bv, bu = np.nonzero(band)
    mv, mu = np.nonzero(crop)
    bv, bu, mv, mu = bv * step + v0, bu * step + u0, mv * step + v0, mu * step + u0
    z_ring, z_in = depth_m[bv, bu], depth_m[mv, mu]
    z_ring, z_in = z_ring[z_ring > 0], z_in[z_in > 0]
    if z_ring.size < min_points or z_in.size < min_points // 4:
        return False
    z_band = float(median(z_ring))
    band_tolerance = tolerance + noise_per_m2 * z_band ** 2
    if z_band - median(z_in) > 4 * band_tolerance:
        return False  # it stands well in front of what is around it: the quick answer
    ring = _points_map(bv, bu, depth_m, intr, T_map_camera)
    inside = _points_map(mv, mu, depth_m, intr, T_map_camera)
    if len(ring) < min_points or len(inside) < min_points // 4:
        return False
    centre, normal = plane_fit(ring)
    # The whole band on one vertical plane; or, failing that (the band also meets a sideboard below
    # a poster), most of it on a vertical plane the camera faces, with nothing seen beyond it.
    if not on_wall(ring, centre, normal, band_tolerance, 0.8, max_tilt):
        if wall_share is None:
            return False
        for centre, normal in wall_planes(ring, z_ring):
            if on_wall(ring, centre, normal, band_tolerance, wall_share, max_tilt, T_map_camera[:3, 3], min_facing):
                break
        else:
            return False
    d = (inside - centre) @ normal
    # Oriented towards the camera: a thing in front of the wall has all its points on that side.
    cam = T_map_camera[:3, 3]
    if (cam - centre) @ normal < 0:
        d = -d
    if noise_per_m2 > 0:
        return bool(abs(median(d)) <= tolerance)
    return bool(median(np.abs(d)) <= tolerance and np.mean(d > tolerance) < 0.5)


def mask_point(mask: np.ndarray, depth_m: np.ndarray, intr: Intrinsics, T_map_camera: np.ndarray,
               step: int = 4) -> np.ndarray | None:
    """The median map-frame point (3,) of a mask's pixels with a depth reading, on a grid of every
    ``step``-th row and column (every pixel when the grid misses the mask); None without a reading."""
    v, u = np.nonzero(mask[::step, ::step])
    v, u = v * step, u * step
    if v.size == 0:
        v, u = np.nonzero(mask)
    points = _points_map(v, u, depth_m, intr, T_map_camera)
    return median(points) if len(points) else None


def picture_hits(boxes: Boxes, top: np.ndarray, points_xyz: np.ndarray, point_top: np.ndarray,
                 margin: float) -> np.ndarray:
    """(M,) int: for each map object (M boxes, top classes (M,)), how many of the frame's flat
    detections of its class (points_xyz (P, 3): a point of each, point_top (P,)) lie in its box
    grown by ``margin`` metres on every side.

    A poster the detector takes for a tv from some views is judged flat from others; the flat views
    were dropped one by one, and the others made an object. Counted on the object, they say what it is.
    """
    if len(boxes) == 0 or len(points_xyz) == 0:
        return np.zeros(len(boxes), dtype=np.int64)
    d = points_xyz[None, :, :] - boxes.center[:, None, :]  # (M, P, 3) in map axes
    local = np.einsum("mji,mpj->mpi", rot_z(boxes.yaw), d)  # R_box^T d: in each box's frame
    inside = np.all(np.abs(local) <= boxes.size[:, None, :] / 2 + margin, axis=-1)
    inside &= top[:, None] == np.asarray(point_top)[None, :]
    return inside.sum(axis=1).astype(np.int64)


def is_picture(n_det: np.ndarray, n_flat: np.ndarray, share: float, min_flat: int) -> np.ndarray:
    """(M,) bool: objects of which at least ``min_flat`` detections, and at least ``share`` of all
    (those that made the object and the flat ones), lay flat on a wall."""
    n_det, n_flat = np.asarray(n_det), np.asarray(n_flat)
    return (n_flat >= min_flat) & (n_flat >= share * (n_det + n_flat))

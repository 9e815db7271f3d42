"""Stage 1, object modeling: instance masks + depth -> Z-oriented boxes with vertex visibility.

Pure numpy / scipy over arrays; no I/O. Section 1 of DESIGN.md and section 3.1 of the paper.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import cv2

from ltc_cli.geometry.boxes import EDGES_BY_AXIS, Boxes, fit_box
from ltc_cli.geometry.camera import backproject, invert_pose, project, transform
from ltc_cli.pipeline.clustering import largest_clusters
from ltc_cli.pipeline.priors import background_gap, deepen_slabs, ground_to_floor, unobserved_far_side
from ltc_cli.types import Intrinsics


#: The image the pixel settings are given for: the paper's 640 x 480, by its longer side.
REFERENCE_SIDE_PX = 640
#: The settings counted in pixels of that image (``modeling.scale_pixels``).
PIXEL_SETTINGS = ("thin_max_iterations", "border", "occlusion_window")
#: Pixels beyond a mask's bounding box where the background around it is read (background_gap).
BACKGROUND_BAND_PX = 8


def pixel_scale(shape: tuple, scale: bool = True) -> float:
    """This image's pixels per pixel of a 640 x 480 image, by the longer side, and never under 1
    (1.0 when ``scale`` is false). A CNN's mask is blurred by a share of the image, not by a number
    of pixels: YOLO's come from an 80 x 80 grid over its letterboxed input, so its bleed is 8 px at
    640 x 480 and 16 px at 1280 x 720; thinning 5 px there leaves half of it (on tum-fr1-rpy drawn
    at twice the size, the two chairs' bled masks made one 1.4 x 2.0 m "chair"). Smaller images
    keep the paper's pixels: drawn at half the size, tum-fr1-rpy held 37 of 39 places with them and
    35 with half of them (docs/decisions.md, issue 9 forty-ninth round)."""
    return max(1.0, max(int(shape[0]), int(shape[1])) / REFERENCE_SIDE_PX) if scale else 1.0


def scaled_px(n: int, scale: float) -> int:
    """``n`` pixels of a 640 x 480 image in one ``scale`` times as long: rounded half up, and at
    least 1 where ``n`` is."""
    if n <= 0:
        return int(n)
    return max(1, int(np.floor(n * scale + 0.5)))


def image_settings(p: dict, shape: tuple) -> tuple[dict, float]:
    """(the modeling settings ``p`` with their pixel counts (``PIXEL_SETTINGS``) for an image of
    this shape, the scale): ``p`` itself for a 640-pixel-long image or ``scale_pixels`` false."""
    s = pixel_scale(shape, bool(p.get("scale_pixels", False)))
    if s == 1.0:
        return p, s
    out = dict(p)
    for key in PIXEL_SETTINGS:
        out[key] = scaled_px(int(p[key]), s)
    return out, s


def thin_iterations(mask_h: int, mask_w: int, max_iterations: int, fraction: float) -> int:
    """Thinning iterations for a mask whose bounding box is mask_h x mask_w pixels."""
    return int(min(max_iterations, fraction * min(mask_h, mask_w)))


def thin_crop(mask: np.ndarray, max_iterations: int, fraction: float):
    """Thin a (H, W) bool mask by k iterations of 3x3 erosion, k = min(max, fraction * short side).

    The number of iterations follows the mask's own size so that a small, far object keeps most of
    its pixels while a large one loses the boundary band where masks bleed onto neighbours.
    k iterations of a 3x3 erosion equal one (2k+1)x(2k+1) minimum filter, which is separable, so
    the work is done on the mask's bounding box only. The image border does not erode.

    Returns (crop (h, w) bool, row0, col0, k): the thinned mask within its bounding box (plus the
    margin) and where that box starts in the image; crop is None for an empty mask.
    """
    rows = np.flatnonzero(mask.any(axis=1))
    if rows.size == 0:
        return None, 0, 0, 0
    r0, r1 = rows[0], rows[-1] + 1
    cols = np.flatnonzero(mask[r0:r1].any(axis=0))
    c0, c1 = cols[0], cols[-1] + 1
    k = thin_iterations(r1 - r0, c1 - c0, max_iterations, fraction)
    h, w = mask.shape
    # A margin of k zeros around the mask, except where the image ends: a mask cut by the image
    # border did not bleed there, and eroding it would move a cut edge inwards, where its vertices
    # would pass the border test and a partial view would look complete.
    R0, R1, C0, C1 = max(r0 - k, 0), min(r1 + k, h), max(c0 - k, 0), min(c1 + k, w)
    crop = mask[R0:R1, C0:C1]
    if k > 0:
        # A binary erosion by a (2k+1)^2 square: OpenCV's, the same pixels as scipy.ndimage's
        # minimum_filter (mode "nearest"; tests/test_modeling.py), without importing ndimage in an
        # ingest (~0.04 s CPU). Replicated borders never lower a minimum that the window did not hold.
        kernel = np.ones((2 * k + 1, 2 * k + 1), np.uint8)
        crop = cv2.erode(crop.view(np.uint8), kernel, borderType=cv2.BORDER_REPLICATE).view(bool)
    return crop, R0, C0, k


def thin_mask(mask: np.ndarray, max_iterations: int, fraction: float) -> np.ndarray:
    """The thinned mask at full size (see :func:`thin_crop`)."""
    crop, r0, c0, _ = thin_crop(mask, max_iterations, fraction)
    out = np.zeros_like(mask)
    if crop is not None:
        out[r0 : r0 + crop.shape[0], c0 : c0 + crop.shape[1]] = crop
    return out


def mask_pixels(crop: np.ndarray, r0: int, c0: int, depth_m: np.ndarray, max_points: int,
                min_depth: float, max_depth: float, edge_jump: float | None = None):
    """A regular subsample of a mask's pixels with depth in range.

    crop (h, w) bool is the mask's part starting at image row r0, column c0. Keeps the pixels whose
    image coordinates are multiples of the stride, so that at most about max_points remain.
    Returns (u (N,), v (N,), z (N,), stride).
    """
    n = int(np.count_nonzero(crop))
    if n == 0:
        return np.zeros(0, int), np.zeros(0, int), np.zeros(0, dtype=np.float32), 1
    stride = max(1, int(np.ceil(np.sqrt(n / max_points))))
    sr, sc = (-r0) % stride, (-c0) % stride
    vv, uu = np.nonzero(crop[sr::stride, sc::stride])
    v = r0 + sr + vv * stride
    u = c0 + sc + uu * stride
    z = depth_m[v, u]
    ok = (z > min_depth) & (z < max_depth)
    if edge_jump:
        ok &= ~depth_edges(depth_m, u, v, z, edge_jump)
    return u[ok], v[ok], z[ok], stride


def valid_depth_share(crop: np.ndarray, r0: int, c0: int, depth_m: np.ndarray, min_depth: float,
                      max_depth: float) -> float:
    """The share (0..1) of a thinned mask's pixels with a depth reading in (min_depth, max_depth).

    crop (h, w) bool is the thinned mask's part starting at image row r0, column c0. A dark or shiny
    screen gives no depth, and what few points its mask keeps are whatever it bleeds onto; 0 for an
    empty mask.
    """
    n = int(np.count_nonzero(crop))
    if n == 0:
        return 0.0
    z = depth_m[r0 : r0 + crop.shape[0], c0 : c0 + crop.shape[1]][crop]
    return float(np.count_nonzero((z > min_depth) & (z < max_depth))) / n


def mask_coverage(corners_cam: np.ndarray, crop: np.ndarray, r0: int, c0: int, intr: Intrinsics) -> float:
    """The share (0..1) of a mask's pixels inside the image outline of its box.

    corners_cam (8, 3): the box's corners in the camera frame; crop (h, w) bool: the mask's part
    starting at image row r0, column c0. 1 when a corner is behind the camera (a box around it
    explains whatever the mask shows) or the mask is empty.
    """
    n = int(np.count_nonzero(crop))
    if n == 0 or (corners_cam[:, 2] <= 1e-3).any():
        return 1.0
    u, v, _ = project(corners_cam, intr)
    outline = np.stack([u - c0, v - r0], axis=1)
    if not np.isfinite(outline).all() or np.abs(outline).max() > 1e6:
        return 1.0
    hull = cv2.convexHull(np.round(outline).astype(np.int32))
    inside = np.zeros(crop.shape, np.uint8)
    cv2.fillConvexPoly(inside, hull, 1)
    return float(np.count_nonzero(inside.astype(bool) & crop)) / n


def depth_edges(depth_m: np.ndarray, u: np.ndarray, v: np.ndarray, z: np.ndarray, jump: float) -> np.ndarray:
    """(N,) True where a pixel's depth differs from a 4-neighbour's by more than ``jump`` * z.

    Depth cameras report "flying pixels" between a foreground edge and the background, mixing both
    depths. Inside a mask they bridge an object to the wall behind it, and a clustering of
    neighbouring points (voxel components, like DBSCAN with small min_samples) would follow the
    bridge; dropping pixels at depth jumps removes the bridges.
    """
    h, w = depth_m.shape
    flat = depth_m.ravel()
    idx = v * w + u
    limit = jump * z
    edge = np.zeros(len(z), dtype=bool)
    # Neighbours by flat index; a point on the image edge compares with itself there (no jump).
    for off, ok in ((1, u < w - 1), (-1, u > 0), (w, v < h - 1), (-w, v > 0)):
        n = flat[np.where(ok, idx + off, idx)]
        edge |= (n > 0) & (np.abs(n - z) > limit)
    return edge


def _regrow(size, center, yaw, cam_xyz, pad_px, z_med, intr):
    """Give back the width that thinning and subsampling took from each side of the mask.

    pad_px pixels at depth z_med are pad_px z_med / f metres. Image rows map to world z; image
    columns to the footprint axes in proportion to how square each axis is to the line of sight.
    """
    view = center[:2] - cam_xyz[:2]
    n = np.hypot(view[0], view[1])
    view = view / n if n > 1e-9 else np.array([1.0, 0.0])
    c, s = np.cos(yaw), np.sin(yaw)
    perp_x = abs(c * view[1] - s * view[0])
    perp_y = abs(-s * view[1] - c * view[0])
    grow_h = 2 * pad_px * z_med / intr.fx
    grow_v = 2 * pad_px * z_med / intr.fy
    return size + np.array([grow_h * perp_x, grow_h * perp_y, grow_v])


def vertex_visibility(
    corners_world: np.ndarray,
    T_camera_world: np.ndarray,
    depth_m: np.ndarray,
    intr: Intrinsics,
    border: float,
    occlusion_tolerance: float,
    window: int = 2,
) -> np.ndarray:
    """Visible flags (M, 8) of box corners (M, 8, 3) seen from a camera.

    A vertex is not visible when it falls behind the camera, outside the image minus ``border``
    pixels, or when the observed depth around its pixel (median of the valid readings in a
    (2 window + 1)^2 patch, robust to single flying pixels) is nearer than the vertex by more than
    ``occlusion_tolerance`` (Z-buffer test). Pixels with no reading do not occlude.
    """
    shape = corners_world.shape[:-1]
    pts = transform(T_camera_world, corners_world.reshape(-1, 3))
    u, v, z = project(pts, intr)
    h, w = depth_m.shape
    inside = (z > 1e-6) & (u >= border) & (u < w - border) & (v >= border) & (v < h - border)
    vis = inside.copy()
    idx = np.flatnonzero(inside)
    if idx.size:
        ui = np.clip(np.round(u[idx]).astype(int), 0, w - 1)
        vi = np.clip(np.round(v[idx]).astype(int), 0, h - 1)
        d = np.arange(-window, window + 1)
        uu = np.clip(ui[:, None, None] + d[None, None, :], 0, w - 1)
        vv = np.clip(vi[:, None, None] + d[None, :, None], 0, h - 1)
        patch = depth_m[vv, uu].reshape(len(idx), -1).astype(np.float64)
        valid = patch > 0
        nvalid = valid.sum(axis=1)
        patch[~valid] = np.inf
        patch.sort(axis=1)
        has = nvalid > 0
        med = np.full(len(idx), np.inf)
        med[has] = patch[has, (nvalid[has] - 1) // 2]
        occluded = med < z[idx] - occlusion_tolerance
        vis[idx[occluded]] = False
    return vis.reshape(shape)


def defined_flags(visible: np.ndarray) -> np.ndarray:
    """A box is Defined (M,) when, for each of its 3 axes, some edge along it has both ends visible."""
    out = np.ones(visible.shape[:-1], dtype=bool)
    for edges in EDGES_BY_AXIS:
        out &= (visible[..., edges[:, 0]] & visible[..., edges[:, 1]]).any(axis=-1)
    return out


@dataclass
class ModeledDetections:
    """The boxes of one frame's detections that survived modeling.

    boxes: Boxes (M,) in the map frame, with visible flags; defined (M,) bool;
    source (M,) index of each box's detection in the detector's list; n_points (M,);
    bottom_gap (M,): metres from the floor to the bottom of the box as seen, before grounding (NaN:
    no floor height; None: not computed).
    """

    boxes: Boxes
    defined: np.ndarray
    source: np.ndarray
    n_points: np.ndarray
    bottom_gap: np.ndarray | None = None

    def take(self, keep: np.ndarray) -> "ModeledDetections":
        gap = None if self.bottom_gap is None else self.bottom_gap[keep]
        return ModeledDetections(self.boxes.take(keep), self.defined[keep], self.source[keep], self.n_points[keep], gap)


def model_detections(
    masks: list[np.ndarray],
    depth_m: np.ndarray,
    intr: Intrinsics,
    T_map_camera: np.ndarray,
    p: dict,
    depth_range: tuple[float, float],
    grounded: np.ndarray | None = None,
    floor_z: float | None = None,
    class_depth: np.ndarray | None = None,
    weighted: np.ndarray | None = None,
    max_floor_gap: np.ndarray | None = None,
) -> ModeledDetections:
    """Masks (H, W) of one frame -> boxes in the map frame (DESIGN.md 1.1).

    thinning -> eq. 1 back-projection of a subsample -> map frame -> largest cluster -> exact
    minimum-area Z-oriented box -> drop specks and out-of-range boxes -> vertex visibility ->
    Defined. Pixel settings are for a 640 x 480 image and scale up with a larger one
    (:func:`image_settings`). ``weighted`` (one bool per mask): whose points count for the pixels
    they stand for (``pixel_weights`` by class); None: every mask's when ``pixel_weights`` is true,
    none otherwise.
    ``max_floor_gap`` (one per mask, inf: none): a ``grounded`` box whose bottom lies higher above
    the floor than this is not grounded (it is no object of its class, ``modeling.higher_than``).
    """
    min_d, max_d = depth_range
    p, scale = image_settings(p, depth_m.shape)
    band = scaled_px(BACKGROUND_BAND_PX, scale)
    pts_list, groups, sources, pads, backs, weights, crops = [], [], [], [], [], [], []
    for i, mask in enumerate(masks):
        crop, r0, c0, k = thin_crop(mask, p["thin_max_iterations"], p["thin_fraction"])
        if crop is None:
            continue
        # Too few depth readings on the mask: the points are not the object's (None: keep all).
        share = valid_depth_share(crop, r0, c0, depth_m, min_d, max_d) \
            if p.get("min_depth_share") is not None or p.get("min_mask_explained") is not None else 1.0
        if p.get("min_depth_share") is not None and share < p["min_depth_share"]:
            continue
        u, v, z, stride = mask_pixels(crop, r0, c0, depth_m, p["max_points"], min_d, max_d, p["edge_jump"])
        if len(z) < p["min_samples"]:
            continue
        # Pixels lost at each side: the thinning band, and on average half a subsampling step.
        pads.append((k + (stride - 1) / 2.0, float(np.median(z))))
        backs.append(background_gap(depth_m, (r0, r0 + crop.shape[0] - 1), (c0, c0 + crop.shape[1] - 1),
                                     pads[-1][1], band))
        pts_cam = backproject(u, v, z, intr)
        pts_list.append(transform(T_map_camera, pts_cam))
        groups.append(np.full(len(z), len(sources)))
        weights.append(np.full(len(z), float(stride * stride) if weighted is None or weighted[i] else 1.0))
        sources.append(i)
        crops.append((crop, r0, c0, share))
    empty = ModeledDetections(
        Boxes(np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3)), np.zeros((0, 8), bool)),
        np.zeros(0, bool), np.zeros(0, int), np.zeros(0, int),
    )
    if not pts_list:
        return empty
    points = np.concatenate(pts_list)
    group = np.concatenate(groups)
    # pixel_weights: a subsampled point stands for the stride^2 pixels around it, so DBSCAN's
    # density is the whole mask's (as if every pixel were clustered, the paper's); counted once, a
    # large mask's sparse parts (a bed top at a grazing angle, 10 cm between points) are noise.
    w = np.concatenate(weights) if weighted is not None or p.get("pixel_weights") is True else None
    clusters = largest_clusters(points, group, p["eps"], p["min_samples"], p["clustering"], p.get("stack_gap"), w)
    centers, yaws, sizes, src, npts, gaps, kept = [], [], [], [], [], [], []
    for g, idx in enumerate(clusters):
        if idx is None:
            continue
        center, yaw, size = fit_box(points[idx])
        if size.max() < p["min_extent"]:
            continue
        if p["compensate_thinning"]:
            size = _regrow(size, center, yaw, T_map_camera[:3, 3], *pads[g], intr)
        # A single view of a flat face has no thickness: pad thin sides to the minimum extent.
        size = np.maximum(size, p["min_extent"])
        centers.append(center)
        yaws.append(yaw)
        sizes.append(size)
        gaps.append(backs[g])
        src.append(sources[g])
        kept.append(g)
        npts.append(len(idx))
    if not centers:
        return empty
    boxes = Boxes(np.array(centers), np.array(yaws), np.array(sizes), np.zeros((len(centers), 8), bool))
    boxes.visible = vertex_visibility(
        boxes.corners,
        invert_pose(T_map_camera),
        depth_m,
        intr,
        p["border"],
        p["occlusion_tolerance"],
        p["occlusion_window"],
    )
    if p["thin_extent"]:
        boxes.visible &= ~unobserved_far_side(boxes, T_map_camera[:3, 3], p["thin_extent"])
        if class_depth is not None:
            deepen_slabs(boxes, np.asarray(class_depth)[np.array(src)], np.array(gaps), T_map_camera[:3, 3],
                         p["thin_extent"])
    gap = np.full(len(src), np.nan) if floor_z is None else boxes.center[:, 2] - boxes.size[:, 2] / 2 - floor_z
    if grounded is not None and floor_z is not None:
        grounded = np.asarray(grounded)[np.array(src)]
        if max_floor_gap is not None:
            grounded = grounded & ~(gap > np.asarray(max_floor_gap)[np.array(src)])
        ground_to_floor(boxes, grounded, floor_z, p["ground_max_gap"])
    out = ModeledDetections(boxes, defined_flags(boxes.visible), np.array(src), np.array(npts), gap)
    explained = p.get("min_mask_explained")
    if explained is None or all(crops[g][3] >= explained for g in kept):
        return out
    # Little of the mask had depth and the box drawn back into the image covers little of the
    # mask: the points are what the mask bled onto (the clutter in front of a dark screen on
    # tum-fr1-rpy), not the object the detector saw.
    T_camera_map = invert_pose(T_map_camera)
    keep = [k for k, g in enumerate(kept) if crops[g][3] >= explained
            or mask_coverage(transform(T_camera_map, boxes.corners[k]), *crops[g][:3], intr) >= explained]
    if len(keep) == len(kept):
        return out
    return out.take(np.array(keep, dtype=int))

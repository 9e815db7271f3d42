"""Exact polygon geometry of Z-oriented box footprints: convex clipping, XY IoU, VIoU.

The footprints are rectangles; their intersection is a convex polygon of at most 8 vertices,
computed by Sutherland-Hodgman clipping (vectorised over many box pairs at once) and measured with
the shoelace formula. Two Z-oriented boxes intersect in a prism: footprint intersection times the
overlap of the z intervals.
"""

from __future__ import annotations

import numpy as np

from ltc_cli.geometry.boxes import box_corners


def _clip_half_plane(poly, count, a, b):
    """Clip convex polygons by the left half-plane of the directed lines a -> b.

    poly (P, K, 2) padded vertices (counter-clockwise), count (P,) valid vertices per polygon,
    a, b (P, 2). Returns (poly (P, K + 1, 2), count (P,)). Points exactly on the line are kept, so
    identical boxes clip to themselves.
    """
    P, K, _ = poly.shape
    slot = np.arange(K)[None, :]
    valid = slot < count[:, None]
    nxt_idx = (slot + 1) % np.maximum(count, 1)[:, None]
    cur = poly
    nxt = np.take_along_axis(poly, nxt_idx[:, :, None], axis=1)
    d = (b - a)[:, None, :]
    s_cur = d[..., 0] * (cur[..., 1] - a[:, None, 1]) - d[..., 1] * (cur[..., 0] - a[:, None, 0])
    s_nxt = d[..., 0] * (nxt[..., 1] - a[:, None, 1]) - d[..., 1] * (nxt[..., 0] - a[:, None, 0])
    in_cur, in_nxt = s_cur >= 0, s_nxt >= 0
    cross = (in_cur != in_nxt) & valid
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(cross, s_cur / (s_cur - s_nxt), 0.0)
    inter = cur + t[..., None] * (nxt - cur)
    # Each edge cur -> nxt emits [intersection if it crosses, nxt if nxt is inside].
    out = np.stack([inter, nxt], axis=2).reshape(P, 2 * K, 2)
    keep = np.stack([cross, in_nxt & valid], axis=2).reshape(P, 2 * K)
    order = np.argsort(~keep, axis=1, kind="stable")[:, : K + 1]
    out = np.take_along_axis(out, order[:, :, None], axis=1)
    return out, keep.sum(axis=1)


def _polygon_area(poly, count):
    """Shoelace area (P,) of padded counter-clockwise polygons poly (P, K, 2), count (P,)."""
    P, K, _ = poly.shape
    if K == 0:
        return np.zeros(P)
    slot = np.arange(K)[None, :]
    valid = slot < count[:, None]
    nxt = np.take_along_axis(poly, ((slot + 1) % np.maximum(count, 1)[:, None])[:, :, None], axis=1)
    cross = poly[..., 0] * nxt[..., 1] - poly[..., 1] * nxt[..., 0]
    area = 0.5 * np.where(valid, cross, 0.0).sum(axis=1)
    return np.where(count >= 3, np.maximum(area, 0.0), 0.0)


def _clipped_area_one(poly_a: list, poly_b: list) -> float:
    """The area of the intersection of two convex polygons given as lists of (x, y) floats,
    counter-clockwise: :func:`_clip_half_plane` and :func:`_polygon_area` for one pair, in plain
    floats: the same operations in the same order, so the same area within a rounding (numpy's sum
    over a batch's padded polygons may add in another order). It spares a pair the cost of some
    hundred small numpy operations."""
    poly = poly_a
    kb = len(poly_b)
    for k in range(kb):
        if not poly:
            break
        ax, ay = poly_b[k]
        bx, by = poly_b[(k + 1) % kb]
        dx, dy = bx - ax, by - ay
        side = [dx * (y - ay) - dy * (x - ax) for x, y in poly]
        out = []
        n = len(poly)
        for i in range(n):
            j = (i + 1) % n
            s_cur, s_nxt = side[i], side[j]
            if (s_cur >= 0) != (s_nxt >= 0):
                t = s_cur / (s_cur - s_nxt)
                (cx, cy), (nx, ny) = poly[i], poly[j]
                out.append((cx + t * (nx - cx), cy + t * (ny - cy)))
            if s_nxt >= 0:
                out.append(poly[j])
        poly = out
    n = len(poly)
    if n < 3:
        return 0.0
    terms = [x0 * y1 - y0 * x1 for (x0, y0), (x1, y1) in zip(poly, poly[1:] + poly[:1])]
    total = terms[0]
    for term in terms[1:]:
        total += term
    return max(0.5 * total, 0.0)


# Up to this many pairs the plain floats are faster than numpy (about 0.015 ms a pair against
# 0.45 ms a call and more; they cross near 45 pairs: benchmarks/bench_polygons.py).
FEW_PAIRS = 32


def convex_intersection_area(poly_a, poly_b) -> np.ndarray:
    """Areas (P,) of the intersections of convex polygons poly_a (P, Ka, 2) and poly_b (P, Kb, 2),
    both counter-clockwise, all vertices valid."""
    poly_a = np.asarray(poly_a, dtype=np.float64)
    poly_b = np.asarray(poly_b, dtype=np.float64)
    P, Kb = poly_b.shape[0], poly_b.shape[1]
    if P <= FEW_PAIRS:
        return np.array([_clipped_area_one([tuple(v) for v in a], [tuple(v) for v in b])
                         for a, b in zip(poly_a.tolist(), poly_b.tolist())], dtype=np.float64).reshape(P)
    poly = poly_a.copy()
    count = np.full(P, poly_a.shape[1])
    for k in range(Kb):
        poly, count = _clip_half_plane(poly, count, poly_b[:, k], poly_b[:, (k + 1) % Kb])
        # Drop padding slots no polygon uses, so the arrays do not grow by one per clip needlessly.
        poly = poly[:, : max(int(count.max(initial=0)), 1)]
    return _polygon_area(poly, count)


def pairwise_ious_arrays(center_a, yaw_a, size_a, center_b, yaw_b, size_b):
    """Exact XY IoU and VIoU of every pair of boxes a (M) and b (G).

    center_* (N, 3), yaw_* (N,), size_* (N, 3). Returns (xy_iou (M, G), viou (M, G)), both in [0, 1].
    Pairs whose footprints' bounding circles do not meet are skipped (IoU 0) so a few hundred
    boxes against a few hundred cost only the pairs that are close.
    """
    center_a = np.asarray(center_a, dtype=np.float64).reshape(-1, 3)
    center_b = np.asarray(center_b, dtype=np.float64).reshape(-1, 3)
    size_a = np.asarray(size_a, dtype=np.float64).reshape(-1, 3)
    size_b = np.asarray(size_b, dtype=np.float64).reshape(-1, 3)
    yaw_a = np.asarray(yaw_a, dtype=np.float64).reshape(-1)
    yaw_b = np.asarray(yaw_b, dtype=np.float64).reshape(-1)
    M, G = len(center_a), len(center_b)
    xy = np.zeros((M, G))
    vol = np.zeros((M, G))
    if M == 0 or G == 0:
        return xy, vol

    ia, ib = np.nonzero(footprint_circles_meet(center_a[:, None], size_a[:, None], center_b[None], size_b[None]))
    if len(ia) == 0:
        return xy, vol
    xy[ia, ib], vol[ia, ib] = paired_ious(center_a[ia], yaw_a[ia], size_a[ia], center_b[ib], yaw_b[ib], size_b[ib])
    return xy, vol


def footprint_circles_meet(center_a, size_a, center_b, size_b) -> np.ndarray:
    """Whether the circles around two boxes' footprints meet (centres (..., 3), sizes (..., 3),
    broadcast): boxes whose circles do not meet share no ground, and need no clipping."""
    rad_a = 0.5 * np.hypot(size_a[..., 0], size_a[..., 1])
    rad_b = 0.5 * np.hypot(size_b[..., 0], size_b[..., 1])
    gap = np.hypot(center_a[..., 0] - center_b[..., 0], center_a[..., 1] - center_b[..., 1])
    return gap <= rad_a + rad_b + 1e-9


def paired_ious(center_a, yaw_a, size_a, center_b, yaw_b, size_b):
    """Exact XY IoU and VIoU (K,) of each pair of boxes (a[k], b[k]): center_* (K, 3), yaw_* (K,),
    size_* (K, 3). Both in [0, 1]."""
    area_a = size_a[:, 0] * size_a[:, 1]
    area_b = size_b[:, 0] * size_b[:, 1]
    # Footprints relative to the centre of box a: keeps coordinates small (shoelace precision).
    origin = center_a[:, :2]
    fa = box_corners(center_a, yaw_a, size_a)[:, :4, :2] - origin[:, None, :]
    fb = box_corners(center_b, yaw_b, size_b)[:, :4, :2] - origin[:, None, :]
    inter = convex_intersection_area(fa, fb)
    # Exact limits: the intersection never exceeds the smaller footprint.
    inter = np.minimum(inter, np.minimum(area_a, area_b))

    union = area_a + area_b - inter
    with np.errstate(divide="ignore", invalid="ignore"):
        iou = np.where(union > 0, inter / union, 0.0)

    za0, za1 = center_a[:, 2] - size_a[:, 2] / 2, center_a[:, 2] + size_a[:, 2] / 2
    zb0, zb1 = center_b[:, 2] - size_b[:, 2] / 2, center_b[:, 2] + size_b[:, 2] / 2
    dz = np.clip(np.minimum(za1, zb1) - np.maximum(za0, zb0), 0.0, None)
    inter_v = inter * dz
    union_v = area_a * size_a[:, 2] + area_b * size_b[:, 2] - inter_v
    with np.errstate(divide="ignore", invalid="ignore"):
        viou = np.where(union_v > 0, inter_v / union_v, 0.0)
    return np.clip(iou, 0.0, 1.0), np.clip(viou, 0.0, 1.0)

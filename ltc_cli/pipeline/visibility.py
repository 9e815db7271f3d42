"""Stage 4's eyes: which pixels of each map box the camera should see in a frame, and what the
depth observed there (hidden by other boxes or by something nearer, seen through).

Pure numpy, one ray per step x step pixel block, the boxes' slabs intersected exactly (DESIGN.md
1.4: "in view, in range, enough pixels not hidden by other map objects or by the observed depth").
maintenance.py turns these counts into non-detections and removals.
"""

from __future__ import annotations

import numpy as np

from ltc_cli.geometry.boxes import Boxes
from ltc_cli.geometry.camera import invert_pose, project, transform
from ltc_cli.types import Intrinsics


def ray_grid(intr: Intrinsics, step: int):
    """Pixel centres (u (P,), v (P,)) of one ray per step x step block."""
    us = np.arange(step / 2 - 0.5, intr.width, step)
    vs = np.arange(step / 2 - 0.5, intr.height, step)
    uu, vv = np.meshgrid(us, vs)
    return uu.ravel(), vv.ravel()


def _slab_entries(c, s, o_box, half, dirs_map, with_exit: bool):
    """The slab test of :func:`box_entry_depths` on broadcastable operands: box cos / sin of yaw,
    ray origin in the box frame (3 arrays), half sizes (3 arrays), ray directions in the map frame
    (3 arrays). One expression for the dense (M, P) and the sparse (pairs,) form, so both give the
    same bits for the same box and ray."""
    dx = c * dirs_map[0] + s * dirs_map[1]
    dy = -s * dirs_map[0] + c * dirs_map[1]
    dz = np.broadcast_to(dirs_map[2], dx.shape)
    tmin = np.full(dx.shape, -np.inf)
    tmax = np.full(dx.shape, np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        for axis, d in enumerate((dx, dy, dz)):
            inv = 1.0 / np.where(np.abs(d) < 1e-12, 1e-12, d)
            t1 = (-half[axis] - o_box[axis]) * inv
            t2 = (half[axis] - o_box[axis]) * inv
            tmin = np.maximum(tmin, np.minimum(t1, t2))
            tmax = np.minimum(tmax, np.maximum(t1, t2))
    entry = np.maximum(tmin, 0.0)
    hit = tmax >= entry
    if with_exit:
        return np.where(hit, entry, np.inf), np.where(hit, tmax, np.inf)
    return np.where(hit, entry, np.inf)


def _box_frame(boxes: Boxes, T_map_camera: np.ndarray, intr: Intrinsics, u, v):
    """(cos yaw (M,), sin yaw (M,), camera centre in each box frame (M, 3), ray directions in the
    map frame (P, 3)) for the slab test."""
    dirs_cam = np.stack([(u - intr.cx) / intr.fx, (v - intr.cy) / intr.fy, np.ones_like(u)], axis=-1)
    R, o = T_map_camera[:3, :3], T_map_camera[:3, 3]
    dirs_map = dirs_cam @ R.T  # (P, 3)
    c, s = np.cos(boxes.yaw), np.sin(boxes.yaw)
    # Rotate into each box frame: x' = c x + s y, y' = -s x + c y (R_box^T).
    rel = o - boxes.center  # (M, 3)
    o_box = np.stack([c * rel[:, 0] + s * rel[:, 1], -s * rel[:, 0] + c * rel[:, 1], rel[:, 2]], -1)
    return c, s, o_box, dirs_map


def box_entry_depths(boxes: Boxes, T_map_camera: np.ndarray, intr: Intrinsics, u, v, with_exit: bool = False):
    """Camera depth (M, P) where the ray of pixel (u, v) enters each box; inf where it misses.

    Slab test in each box's own frame. The ray directions have z = 1 in the camera frame, so the ray
    parameter is the camera depth Z and compares directly with the depth image.
    """
    c, s, o_box, dirs_map = _box_frame(boxes, T_map_camera, intr, u, v)
    half = boxes.size / 2
    return _slab_entries(c[:, None], s[:, None], [o_box[:, a, None] for a in range(3)],
                         [half[:, a, None] for a in range(3)], [dirs_map[None, :, a] for a in range(3)], with_exit)


def box_ray_pairs(boxes: Boxes, T_map_camera: np.ndarray, intr: Intrinsics, step: int):
    """(box (Q,), ray (Q,)) indices: the rays of :func:`ray_grid` that may hit each box, those
    within a pixel of the box's projected corners (a convex box in front of the camera images
    inside its corners' hull); every ray for a box that comes within 5 cm of the camera plane.

    A ray left out misses its box by a pixel or more, where the slab test gives inf: the counts of
    :func:`pixel_counts` are those of every ray against every box, at a cost that grows with the
    boxes' image areas, not with boxes x rays (issue 11)."""
    us = np.arange(step / 2 - 0.5, intr.width, step)
    vs = np.arange(step / 2 - 0.5, intr.height, step)
    m = len(boxes)
    pts = transform(invert_pose(T_map_camera), boxes.corners)  # (M, 8, 3)
    near = (pts[..., 2] < 0.05).any(axis=1)
    u, v, _ = project(np.where(near[:, None, None], 1.0, pts), intr)
    c0 = np.where(near, 0, np.searchsorted(us, u.min(axis=1) - 1.0, "left"))
    c1 = np.where(near, len(us), np.searchsorted(us, u.max(axis=1) + 1.0, "right"))
    r0 = np.where(near, 0, np.searchsorted(vs, v.min(axis=1) - 1.0, "left"))
    r1 = np.where(near, len(vs), np.searchsorted(vs, v.max(axis=1) + 1.0, "right"))
    w, h = np.maximum(c1 - c0, 0), np.maximum(r1 - r0, 0)
    n = w * h
    box = np.repeat(np.arange(m), n)
    k = np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)
    row, col = r0[box] + k // np.maximum(w[box], 1), c0[box] + k % np.maximum(w[box], 1)
    return box, row * len(us) + col


def pixel_counts(
    boxes: Boxes,
    T_map_camera: np.ndarray,
    depth_m: np.ndarray,
    intr: Intrinsics,
    step: int,
    depth_tolerance: float,
    depth_range: tuple[float, float],
    with_empty: bool = False,
    hidden_by_whole_box: bool = False,
    with_whole_box: bool = False,
    hide_needs_depth: bool | str = False,
    past_middle: float | None = None,
    unread: bool = False,
):
    """Pixels of each box that the camera should see: (visible (M,), projected (M,)), and with
    ``with_empty`` also empty (M,): those of the visible pixels whose observed depth lies beyond
    the far side of the box by more than ``depth_tolerance`` (the camera saw through where the box
    is: free space, whatever the detector says).

    ``projected`` counts the pixels of each box's image within the depth range, whatever hides
    them. ``visible`` counts those whose ray enters the box first among the given boxes (not hidden
    by other map objects) and where the observed depth has a reading that is not nearer than the box
    surface by more than ``depth_tolerance`` (not hidden by something that is not in the map, such as
    a person). Counted at one ray per step x step block and scaled back to pixels.

    ``hidden_by_whole_box``: another box hides a ray only when the ray leaves that box before it
    enters this one (the other box lies wholly in front along the ray), not merely enters it first.
    ``with_whole_box``: also return the visible pixels by the whole-box rule (after ``empty``).
    ``past_middle`` (metres): also return (last) those of the visible pixels (by the whole-box rule
    when ``with_whole_box``) whose observed depth lies beyond the middle of the box along the ray
    by more than this: the ray went through where the object's near half would be. A cup taken
    from a table leaves rays that end on the table top at the box's bottom, past its middle but not
    past its far side; a cup still there stops them at its near surface.
    A cup on a table lies inside the table's box: every ray to the cup enters the table's box first,
    so by the entry test alone the cup is never visible and never missed, and a cup taken away stays
    in the map for ever. A chair in front of a cabinet still hides it (its box ends before).

    ``hide_needs_depth``: a box hides a ray only where the observed depth ends in it or before its
    far side (or there is no reading): a box is coarser than its object (a chair's box is solid
    where its back is slats and air), and where the camera saw past the box, nothing in it hid
    what lies beyond. Without it, a cup taken from a table behind a chair's box was never seen to
    be gone (issue 9, sixth round). ``"absence"``: for the whole-box count only.

    ``unread``: also return (last) the pixels that the rule of the visible count returned just
    before leaves unhidden but where the depth has no reading (a dark screen, a shiny basin).
    """
    m = len(boxes)
    if m == 0:
        return (np.zeros(0),) * (3 if with_empty else 2)
    u, v = ray_grid(intr, step)
    # Only the (box, ray) pairs that may hit (box_ray_pairs): the same entry depths, bit for bit,
    # as the dense (M, P) slab test (tests/test_maintenance.py), whose arrays outgrew the caches.
    box, ray = box_ray_pairs(boxes, T_map_camera, intr, step)
    c, s, o_box, dirs_map = _box_frame(boxes, T_map_camera, intr, u, v)
    half, d = boxes.size / 2, dirs_map[ray]
    entry, exit_ = _slab_entries(c[box], s[box], [o_box[box, a] for a in range(3)], [half[box, a] for a in range(3)],
                                 [d[:, a] for a in range(3)], with_exit=True)  # (Q,)
    in_range = np.isfinite(entry) & (entry >= depth_range[0]) & (entry <= depth_range[1])
    obs = depth_m[v.astype(int), u.astype(int)][ray]
    depth_ok = in_range & (obs > 0) & (obs >= entry - depth_tolerance)

    boxed = np.isfinite(entry)
    stops = boxed & ((obs <= 0) | (obs <= exit_ + depth_tolerance))

    def unhidden(whole_box, needs_depth):
        # Entry: the first box a ray enters hides the others; whole box: a box hides what lies
        # beyond its exit (a box's own exit is never before its entry: it never hides itself).
        nearest = np.full(len(u), np.inf)
        np.minimum.at(nearest, ray, np.where(stops if needs_depth else boxed, exit_ if whole_box else entry, np.inf))
        return entry <= nearest[ray]

    shown = unhidden(hidden_by_whole_box, hide_needs_depth is True)  # also the unread count's rule
    seen = depth_ok & shown
    scale = float(step * step)

    def per_box(flags):
        return np.bincount(box[flags], minlength=m) * scale

    out = [per_box(seen), per_box(in_range)]
    if with_empty:
        out.append(per_box(seen & (obs > exit_ + depth_tolerance)))
    counted = seen
    if with_whole_box:
        # The same count as the first when both use the whole-box rule and the same depth rule.
        same = hidden_by_whole_box and (hide_needs_depth is True) == bool(hide_needs_depth)
        if not same:
            shown = unhidden(True, bool(hide_needs_depth))
            counted = depth_ok & shown
        out.append(out[0] if same else per_box(counted))
    if past_middle is not None:
        out.append(per_box(counted & (obs > 0.5 * (entry + exit_) + past_middle)))
    if unread:
        out.append(per_box(in_range & (obs <= 0) & shown))
    return tuple(out)


def visible_pixels(boxes, T_map_camera, depth_m, intr, step, depth_tolerance, depth_range) -> np.ndarray:
    """The ``visible`` half of :func:`pixel_counts`: (M,) pixels."""
    return pixel_counts(boxes, T_map_camera, depth_m, intr, step, depth_tolerance, depth_range)[0]


def occupied_pixels(boxes: Boxes, T_map_camera: np.ndarray, depth_m: np.ndarray, intr: Intrinsics, step: int,
                    margin: float, lift: float, past_middle: float | None = None) -> np.ndarray:
    """(M,) pixels whose observed depth ends inside each box grown by ``margin`` metres on every
    side but the bottom, which is raised by ``lift`` (what the box stands on is not in it), and,
    with ``past_middle``, not beyond the camera depth of the box's centre by more than that.

    Something stands where the box is, give or take the localiser's drift: a small thing's box
    lies a few centimetres beside the thing in another view's frame, so its rays pass it and look
    "seen through" while the thing's own surface ends inside the grown box. What lies past the
    box's middle is where rays that saw through it end (a wall the box touches), not the thing."""
    m = len(boxes)
    if m == 0:
        return np.zeros(0)
    top = boxes.center[:, 2] + boxes.size[:, 2] / 2 + margin
    bottom = boxes.center[:, 2] - boxes.size[:, 2] / 2 + lift
    size = boxes.size.copy()
    size[:, :2] += 2 * margin
    size[:, 2] = np.maximum(top - bottom, 1e-3)
    center = boxes.center.copy()
    center[:, 2] = 0.5 * (top + bottom)
    grown = Boxes(center, boxes.yaw, size, boxes.visible)
    u, v = ray_grid(intr, step)
    box, ray = box_ray_pairs(grown, T_map_camera, intr, step)
    c, s, o_box, dirs_map = _box_frame(grown, T_map_camera, intr, u, v)
    obs = depth_m[v.astype(int), u.astype(int)][ray]
    d = dirs_map[ray]
    dx = c[box] * d[:, 0] + s[box] * d[:, 1]
    dy = -s[box] * d[:, 0] + c[box] * d[:, 1]
    # The ray directions have z = 1 in the camera frame: obs * direction is the observed point.
    p_box = np.stack([o_box[box, 0] + obs * dx, o_box[box, 1] + obs * dy, o_box[box, 2] + obs * d[:, 2]], -1)
    inside = (obs > 0) & np.all(np.abs(p_box) <= size[box] / 2, axis=1)
    if past_middle is not None:
        middle_z = transform(invert_pose(T_map_camera), boxes.center)[:, 2]
        inside &= obs <= middle_z[box] + past_middle
    return np.bincount(box[inside], minlength=m) * float(step * step)

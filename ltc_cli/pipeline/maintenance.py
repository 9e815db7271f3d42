"""Stage 4, map maintenance: which map objects should have been seen in a frame, and how much.

Pure numpy. Section 3.4 of the paper; DESIGN.md 1.4.
"""

from __future__ import annotations

import numpy as np

from ltc_cli.geometry.boxes import Boxes
from ltc_cli.geometry.camera import invert_pose, project, transform
from ltc_cli.types import Intrinsics


def in_view(boxes: Boxes, T_camera_map: np.ndarray, intr: Intrinsics, max_depth: float) -> np.ndarray:
    """(M,) bool: boxes that overlap the image and come nearer than max_depth (frustum test).

    Conservative on purpose: a box that straddles the camera plane counts as in view; the precise
    visible-pixel count of :func:`visible_pixels` decides about non-detections.
    """
    if len(boxes) == 0:
        return np.zeros(0, dtype=bool)
    pts = transform(T_camera_map, boxes.corners)  # (M, 8, 3)
    z = pts[..., 2]
    front = z > 1e-3
    u, v, _ = project(np.where(front[..., None], pts, 1.0), intr)
    big = 1e9
    straddle = front.any(axis=1) & ~front.all(axis=1)
    umin = np.where(front, u, big).min(axis=1)
    umax = np.where(front, u, -big).max(axis=1)
    vmin = np.where(front, v, big).min(axis=1)
    vmax = np.where(front, v, -big).max(axis=1)
    overlap = (umax >= 0) & (umin < intr.width) & (vmax >= 0) & (vmin < intr.height)
    near = np.where(front, z, big).min(axis=1) < max_depth
    return front.any(axis=1) & (overlap | straddle) & (near | straddle)


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
    ``with_whole_box``: also return (last) the visible pixels by the whole-box rule.
    A cup on a table lies inside the table's box: every ray to the cup enters the table's box first,
    so by the entry test alone the cup is never visible and never missed, and a cup taken away stays
    in the map for ever. A chair in front of a cabinet still hides it (its box ends before).

    ``hide_needs_depth``: a box hides a ray only where the observed depth ends in it or before its
    far side (or there is no reading): a box is coarser than its object (a chair's box is solid
    where its back is slats and air), and where the camera saw past the box, nothing in it hid
    what lies beyond. Without it, a cup taken from a table behind a chair's box was never seen to
    be gone (issue 9, sixth round). ``"absence"``: for the whole-box count only.
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

    seen = depth_ok & unhidden(hidden_by_whole_box, hide_needs_depth is True)
    scale = float(step * step)

    def per_box(flags):
        return np.bincount(box[flags], minlength=m) * scale

    out = [per_box(seen), per_box(in_range)]
    if with_empty:
        out.append(per_box(seen & (obs > exit_ + depth_tolerance)))
    if with_whole_box:
        # The same count as the first when both use the whole-box rule and the same depth rule.
        same = hidden_by_whole_box and (hide_needs_depth is True) == bool(hide_needs_depth)
        out.append(out[0] if same else per_box(depth_ok & unhidden(True, bool(hide_needs_depth))))
    return tuple(out)


def view_counts(boxes: Boxes, T_map_camera: np.ndarray, depth_m: np.ndarray, intr: Intrinsics,
                depth_range: tuple[float, float], m_cfg: dict):
    """(visible, needed, empty, visible for the absence rule), each (M,) pixels, of boxes in view,
    by the maintenance settings ``m_cfg``: :func:`pixel_counts` with its hiding rules
    (``hidden_by_whole_box``: True for every count, "absence" for the absence rule's only;
    ``hide_needs_depth``) and :func:`required_pixels` scaled from 640x480 to the image."""
    whole = m_cfg["hidden_by_whole_box"]
    vis_px, proj_px, empty_px, *vis_absent = pixel_counts(
        boxes, T_map_camera, depth_m, intr, m_cfg["ray_step"], m_cfg["depth_tolerance"], depth_range,
        with_empty=True, hidden_by_whole_box=whole is True, with_whole_box=whole == "absence",
        hide_needs_depth=m_cfg["hide_needs_depth"])
    scale = (intr.width * intr.height) / (640 * 480)  # pixel thresholds are for 640x480
    need = required_pixels(proj_px, m_cfg["min_visible_pixels"] * scale, m_cfg["min_visible_fraction"],
                           m_cfg["min_pixels_floor"] * scale, m_cfg["min_visible_share"])
    return vis_px, need, empty_px, (vis_absent or [vis_px])[0]


def visible_pixels(boxes, T_map_camera, depth_m, intr, step, depth_tolerance, depth_range) -> np.ndarray:
    """The ``visible`` half of :func:`pixel_counts`: (M,) pixels."""
    return pixel_counts(boxes, T_map_camera, depth_m, intr, step, depth_tolerance, depth_range)[0]


def required_pixels(projected: np.ndarray, min_pixels: float, min_fraction, floor: float,
                    min_share: float = 0.0) -> np.ndarray:
    """Visible pixels (M,) an object needs for a non-detection.

    The paper asks for a fixed ``min_pixels`` (1000 at 640x480), which a cup or a book 2 m away never
    reaches, so a small object that was taken away could never leave the map. With ``min_fraction``
    set, an object whose whole image is smaller needs only that fraction of it visible, and never
    fewer than ``floor`` pixels (about the smallest mask a detector reports). With ``min_share``,
    at least that share of the object's whole image must be visible too.
    """
    need = np.full(projected.shape, float(min_pixels))
    if min_fraction is not None:
        need = np.maximum(floor, np.minimum(need, min_fraction * projected))
    # A detector misses a mostly hidden object far more often than a whole one: its silence about
    # an object of which it saw only a sliver says little. Ask for min_share of the object's image.
    return np.maximum(need, min_share * projected)


def non_detection_vector(n_classes: int, v_other: float) -> np.ndarray:
    """Eq. 4: the class vector (r+1,) of a non-detection: (1 - v_Other) / r per class, v_Other last."""
    v = np.full(n_classes + 1, (1.0 - v_other) / n_classes)
    v[-1] = v_other
    return v


def non_detection_vectors(classes: list[str], v_other: float, per_class: dict | None) -> np.ndarray:
    """Eq. 4 vectors (C, C+1), one per top class of the object that was not detected.

    A calibration may measure v_Other per class: a detector that rarely finds tables says little by
    not finding one, so a table's non-detection weighs less.
    """
    per_class = per_class or {}
    return np.array([non_detection_vector(len(classes), float(per_class.get(c, v_other))) for c in classes])


def other_leads(scores: np.ndarray) -> np.ndarray:
    """(M,) bool: objects whose class vectors (M, C+1) now have `other` (last) as their top entry."""
    scores = np.atleast_2d(scores)
    return scores.argmax(axis=1) == scores.shape[1] - 1


def class_hit_counts(top: np.ndarray, n_clear: np.ndarray, n_nondet: np.ndarray, n_classes: int):
    """(views (C,), hits (C,)) summed over objects by their top class: clear views, and those in
    which the object was detected (a clear view without a detection is a non-detection)."""
    views = np.bincount(top, weights=n_clear, minlength=n_classes).astype(np.int64)
    misses = np.bincount(top, weights=n_nondet, minlength=n_classes).astype(np.int64)
    return views, views - misses


def learnt_detection_rate(views: np.ndarray, hits: np.ndarray, prior: float, prior_views: float) -> np.ndarray:
    """Per-class detection rate (C,) on clearly visible objects: the Beta-prior posterior mean
    (hits + k p0) / (views + k p0 / p0), so a class with few views stays near the prior p0."""
    return (hits + prior_views * prior) / (views + prior_views)


def v_other_from_detection_rate(rate: np.ndarray, score: float, margin: float, lo: float = 0.05,
                                hi: float = 0.9) -> np.ndarray:
    """v_Other (C,) of eq. 4 for a detector that finds a clearly visible object of the class with
    probability ``rate`` and a top score about ``score``.

    Under eq. 3 with a capped weight, the class vector of an object that is there tends to the mean
    of its observations: `other` ~ (1 - p) v_Other from the misses, its class ~ p s from the hits.
    It stays when (1 - p) v_Other < p s; ``margin`` (< 1) keeps it clear of that boundary, so an
    object of a class the detector finds one time in three is not removed by its misses, while one
    that is gone (every clear view a miss) still goes, after more misses the weaker the detector.
    """
    rate = np.clip(np.asarray(rate, dtype=np.float64), 1e-6, 1 - 1e-6)
    return np.clip(margin * rate * score / (1.0 - rate), lo, hi)


def camera_view(T_map_camera: np.ndarray) -> np.ndarray:
    """(6,) the camera's position and forward (optical, +z) axis in the map frame."""
    return np.concatenate([T_map_camera[:3, 3], T_map_camera[:3, 2]])


def new_view(last_views: np.ndarray, view: np.ndarray, min_move: float | None, min_turn_deg: float | None) -> np.ndarray:
    """(M,) bool: whether a view (6,) differs enough from each object's last counted miss (M, 6).

    A detector's misses of one object from nearly the same place and direction are correlated (the
    same blur, angle or lighting), so counting each frame as independent evidence removes real
    objects after one bad second. A miss counts when the camera has moved ``min_move`` metres or
    turned ``min_turn_deg`` degrees since the last counted one (None for both: every miss counts,
    the paper), or when there was none yet (zeros).
    """
    last_views = np.atleast_2d(last_views)
    fresh = ~last_views.any(axis=1)
    if min_move is None and min_turn_deg is None:
        return np.ones(len(last_views), dtype=bool)
    if min_move is not None:
        fresh |= np.linalg.norm(last_views[:, :3] - view[:3], axis=1) >= min_move
    if min_turn_deg is not None:
        cos = np.clip(last_views[:, 3:] @ view[3:], -1.0, 1.0)
        fresh |= np.degrees(np.arccos(cos)) >= min_turn_deg
    return fresh


def tentative(first_session: int, n_det: int, session: int, min_detections: int) -> bool:
    """Whether an object is still tentative: created in this session and detected fewer than
    ``min_detections`` times. Eq. 4 weighs a miss against D observations; with D = 1 one or two
    misses remove it, and a real object the detector finds one time in three is deleted and built
    again, again and again. Whether a tentative object is real is the confirmation rule's question
    (:func:`unconfirmed`, at the session's end: M detections in N clear views), not eq. 4's."""
    return bool(first_session == session and n_det < min_detections)


def unconfirmed(n_det: np.ndarray, n_clear: np.ndarray, min_detections: int, min_share: float | None,
                views: np.ndarray | None = None, min_views: int | None = None) -> np.ndarray:
    """(M,) bool: objects too few detections confirm: fewer than ``min_detections``, or fewer than
    ``min_share`` of the frames in which they were clearly visible (None: no share), or detected
    from fewer than ``min_views`` distinct views (M,) (None: any; 0 views: not counted)."""
    weak = n_det < min_detections
    if min_share is not None:
        weak |= n_det < min_share * n_clear
    if min_views is not None and views is not None:
        # 0: made before ltc counted views (a session resumed after an upgrade): not judged so.
        weak |= (views > 0) & (views < min_views)
    return weak


def found_again(first_session: np.ndarray, last_session: np.ndarray, last_frame: np.ndarray, session: int,
                frame: int, window: int) -> np.ndarray:
    """(M,) bool: objects of an earlier session detected in this one at most ``window`` frames ago.

    Within one pass a detector's misses of an object it found again moments ago say more about the
    detector (an angle it does not know, blur, a run of correlated misses) than about the object:
    things are rarely taken away while the robot looks at them. Such misses are not counted. The
    window is short so that an old box that catches one stray detection (a moved chair's old place
    next to another chair) still collects misses for the rest of the session. Objects created in
    this session are not spared: they have yet to show that they are more than a detector's error.
    """
    return ((np.asarray(first_session) < session) & (np.asarray(last_session) == session)
            & (frame - np.asarray(last_frame) <= window))


def seen_empty(visible_px: np.ndarray, empty_px: np.ndarray, share: float | None) -> np.ndarray:
    """(M,) bool: objects whose visible pixels the camera mostly saw through (at least ``share`` of
    them with observed depth beyond the box; None: never)."""
    if share is None:
        return np.zeros(np.shape(visible_px), dtype=bool)
    return (np.asarray(visible_px) > 0) & (np.asarray(empty_px) >= share * np.asarray(visible_px))


def absent_in_session(active: np.ndarray, first_session: np.ndarray, last_session: np.ndarray,
                      clear_session: np.ndarray, clear_in_session: np.ndarray, session: int, views: int,
                      clear_since_det: np.ndarray | None = None, quiet_sessions: int | None = None,
                      quiet_views: int | None = None) -> np.ndarray:
    """(M,) bool: active objects of earlier sessions seen clearly in at least ``views`` frames of
    this session and detected in none: a whole visit's worth of views, not one unlucky frame
    (``clear_session`` holds the session of the clear views + 1, 0 for none yet).

    With ``quiet_sessions`` (and ``clear_since_det``: clear views without a detection since the
    last detection, over sessions), also those not detected in the last ``quiet_sessions``
    sessions (this one included) whose clear views since their last detection reach ``quiet_views``
    (None: ``views``): a
    chair taken away whose old place each lap sees clearly only two or three times (the room's far
    corner) is as gone after two laps as one seen five times in one.
    """
    quiet = np.asarray(active) & (np.asarray(first_session) < session) & (np.asarray(last_session) < session)
    gone = (np.asarray(clear_session) == session + 1) & (np.asarray(clear_in_session) >= views)
    if quiet_sessions is not None and clear_since_det is not None:
        gone |= ((np.asarray(last_session) <= session - quiet_sessions)
                 & (np.asarray(clear_since_det) >= (views if quiet_views is None else quiet_views)))
    return quiet & gone

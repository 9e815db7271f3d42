"""Stage 3, map integration: fuse a detection box and class vector into a map object.

Pure numpy. Section 3.3 of the paper; DESIGN.md 1.3.
"""

from __future__ import annotations

import numpy as np

from ltc_cli.pipeline.association import vertex_distance
from ltc_cli.geometry.boxes import SHIFTS, Box, align_yaw, box_corners, min_area_rect, rot_z, wrap_yaw
from ltc_cli.geometry.polygons import convex_intersection_area, pairwise_ious_arrays
from ltc_cli.pipeline.modeling import defined_flags


def fuse_scores(s_i: np.ndarray, s_j: np.ndarray, D: float) -> np.ndarray:
    """Eq. 3: s_j,c <- (s_i,c + D s_j,c) / sum_l (s_i,l + D s_j,l).

    s_i (C+1,) is the new observation, s_j (C+1,) the map object's vector, D its weight (the number
    of observations so far, possibly capped). With normalised vectors this is a running mean.
    """
    num = s_i + D * s_j
    return num / num.sum()


def label_weight(capped: float, observations: float, same_label: bool, mode: str) -> float:
    """D of eq. 3 for one detection's class vector.

    ``capped``: the object's capped weight; ``observations``: all its observations so far.
    mode "capped": always the capped weight (an exponential average over the last few labels).
    mode "all": a detection whose top class differs from the object's is fused with the weight of
    every observation (the paper's running mean), one that agrees with the capped weight. A detector
    that calls a chair "couch" in a third of the views does so in runs of nearby views; with the
    capped weight alone the last run decides the label, while the cap is only needed so that misses
    can overtake a class (removal). With "all", the label follows the majority of the evidence, and
    a first wrong label still gives way once most detections say otherwise.
    """
    if mode == "all" and not same_label:
        return max(float(capped), float(observations))
    return float(capped)


def _corresponding_visible(src: Box, dst: Box) -> np.ndarray:
    """src's visible flags (8,) re-indexed onto dst's vertices by the best cyclic shift."""
    _, shift = vertex_distance(src.as_boxes(), dst.as_boxes(), min_visible_pairs=9)
    out = np.zeros(8, dtype=bool)
    out[SHIFTS[int(shift[0])]] = src.visible
    return out


def average_boxes(det: Box, obj: Box, w_det: float, w_obj: float) -> Box:
    """Both Defined: the observation-weighted mean of centre, size and orientation."""
    yaw_i, size_i = align_yaw(obj.yaw, det.yaw, det.size)
    a = w_obj / (w_obj + w_det)
    yaw = a * obj.yaw + (1 - a) * float(yaw_i)
    visible = obj.visible | _corresponding_visible(det, obj)
    return Box(
        a * obj.center + (1 - a) * det.center,
        float(wrap_yaw(yaw)),
        a * obj.size + (1 - a) * size_i,
        visible,
        True,
    )


def enclosing_box(det: Box, obj: Box, erosion: float, min_extent: float, snap: float = 0.1) -> Box:
    """Both partial: the minimum box enclosing both, eroded by ``erosion`` per side.

    The erosion keeps repeated noisy partial views from growing the box without end; it never makes
    the box smaller than the larger of the two boxes along any axis, so identical views do not shrink
    it either. A vertex of the new box is visible when a visible vertex of either box lies within
    ``snap`` metres of it.
    """
    c_det = box_corners(det.center, det.yaw, det.size)
    c_obj = box_corners(obj.center, obj.yaw, obj.size)
    pts = np.concatenate([c_det, c_obj])
    cxy, yaw, (sx, sy) = min_area_rect(pts[:, :2])
    zmin, zmax = pts[:, 2].min(), pts[:, 2].max()
    size = np.array([sx, sy, zmax - zmin]) - 2 * erosion
    _, s_det = align_yaw(yaw, det.yaw, det.size)
    _, s_obj = align_yaw(yaw, obj.yaw, obj.size)
    size = np.maximum(size, np.maximum(s_det, s_obj))
    size = np.maximum(size, min_extent)
    center = np.array([cxy[0], cxy[1], (zmin + zmax) / 2])
    visible = snapped_visible(box_corners(center, yaw, size), np.concatenate([c_det[det.visible], c_obj[obj.visible]]),
                              snap)
    return Box(center, float(yaw), size, visible, bool(defined_flags(visible)))


def snapped_visible(corners: np.ndarray, seen: np.ndarray, snap: float) -> np.ndarray:
    """(8,) bool: the corners (8, 3) of an enclosing box that lie within ``snap`` metres of a seen
    (visible) vertex (K, 3) of the boxes it encloses."""
    if not len(seen):
        return np.zeros(8, dtype=bool)
    return (np.linalg.norm(corners[:, None, :] - seen[None, :, :], axis=-1) <= snap).any(axis=1)


def round_enclosing_box(det: Box, obj: Box, erosion: float, min_extent: float, snap: float = 0.1) -> Box:
    """Both partial, for a thing with no footprint direction (an office chair's five-star base):
    the object's box grown along its own axes to cover the ellipse inscribed in the detection's
    footprint, eroded by ``erosion`` per side. A view's box of a round thing is turned anywhere;
    the smallest rectangle around the corners of two squares of side D turned 45 degrees apart is
    1.31 D on a side (their regular octagon across its flats), while the thing is D across. A view
    aligned with the box encloses as in :func:`enclosing_box` (the inscribed ellipse reaches the
    box's sides along its axes)."""
    phi = det.yaw - obj.yaw
    a, b = det.size[0] / 2, det.size[1] / 2
    reach = np.array([np.hypot(a * np.cos(phi), b * np.sin(phi)), np.hypot(a * np.sin(phi), b * np.cos(phi))])
    d = _in_frame_of(obj, det.center[None, :])[0]
    half = obj.size / 2
    lo = np.minimum(-half[:2], d[:2] - reach)
    hi = np.maximum(half[:2], d[:2] + reach)
    z_det = (det.center[2] - det.size[2] / 2, det.center[2] + det.size[2] / 2)
    z_obj = (obj.center[2] - obj.size[2] / 2, obj.center[2] + obj.size[2] / 2)
    zmin, zmax = min(z_det[0], z_obj[0]), max(z_det[1], z_obj[1])
    size = np.array([hi[0] - lo[0], hi[1] - lo[1], zmax - zmin]) - 2 * erosion
    size = np.maximum(size, np.maximum(obj.size, np.array([2 * reach[0], 2 * reach[1], det.size[2]])))
    size = np.maximum(size, min_extent)
    mid = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2])
    center_xy = obj.center[:2] + rot_z(obj.yaw)[:2, :2] @ mid
    center = np.array([center_xy[0], center_xy[1], (zmin + zmax) / 2])
    seen = np.concatenate([box_corners(det.center, det.yaw, det.size)[det.visible],
                           box_corners(obj.center, obj.yaw, obj.size)[obj.visible]])
    visible = snapped_visible(box_corners(center, obj.yaw, size), seen, snap)
    return Box(center, float(obj.yaw), size, visible, bool(defined_flags(visible)))


def _in_frame_of(whole: Box, points_xyz: np.ndarray) -> np.ndarray:
    """points_xyz (N, 3) in the frame of ``whole`` (origin its centre, x along its yaw)."""
    return (points_xyz - whole.center) @ rot_z(whole.yaw)  # R_world_box^T applied to each row


def reach_beyond(partial: Box, whole: Box) -> float:
    """How far (metres) the footprint of ``partial`` reaches outside the footprint of ``whole``:
    the largest excess of its footprint corners over ``whole``'s half sizes, along ``whole``'s own
    axes (0 when it lies inside)."""
    local = _in_frame_of(whole, box_corners(partial.center, partial.yaw, partial.size))
    excess = np.abs(local[:, :2]) - whole.size[:2] / 2
    return float(max(excess.max(), 0.0))


def square_turn(a_yaw: float, b_yaw: float) -> float:
    """The angle (radians, in [0, pi/4]) between two Z-oriented boxes' axes, modulo a quarter
    turn: a box's x and y axes are interchangeable, so 90 degrees apart is no turn at all."""
    d = (a_yaw - b_yaw) % (np.pi / 2)
    return float(min(d, np.pi / 2 - d))


def extended_box(whole: Box, partial: Box, erosion: float) -> Box:
    """``whole`` grown along its own axes to cover ``partial`` (less ``erosion`` per grown side),
    Defined. The Defined box keeps its orientation: a partial box's yaw is the least measured
    thing about it, and the enclosing rectangle of two boxes turned against each other is a
    diagonal one larger than either."""
    half = whole.size / 2
    local = _in_frame_of(whole, box_corners(partial.center, partial.yaw, partial.size))
    lo = np.minimum(-half, local.min(axis=0) + erosion)
    hi = np.maximum(half, local.max(axis=0) - erosion)
    center = whole.center + rot_z(whole.yaw) @ ((lo + hi) / 2)
    return Box(center, whole.yaw, hi - lo, whole.visible.copy(), True)


def shares_inside(box: Box, centers: np.ndarray, yaws: np.ndarray, sizes: np.ndarray) -> np.ndarray:
    """The share (K,) of the volume of each of K boxes (centers (K, 3), yaws (K,), sizes (K, 3))
    that lies inside ``box``."""
    k = len(centers)
    if k == 0:
        return np.zeros(0)
    origin = box.center[:2]
    footprint = box_corners(box.center, box.yaw, box.size)[:4, :2] - origin
    others = box_corners(centers, yaws, sizes)[:, :4, :2] - origin
    area = convex_intersection_area(np.broadcast_to(footprint, (k, 4, 2)), others)
    lo = np.maximum(box.center[2] - box.size[2] / 2, centers[:, 2] - sizes[:, 2] / 2)
    hi = np.minimum(box.center[2] + box.size[2] / 2, centers[:, 2] + sizes[:, 2] / 2)
    return area * np.clip(hi - lo, 0.0, None) / np.maximum(np.prod(sizes, axis=1), 1e-12)


def takes_in(grown: Box, before: Box, centers: np.ndarray, yaws: np.ndarray, sizes: np.ndarray,
             share: float = 0.5) -> bool:
    """True when ``grown`` holds at least ``share`` of the volume of one of the K other boxes that
    ``before`` held less of: a box that grew over another object. A partial mask that bled into
    the chair beside a table says nothing of the table's extent, and the table must not take the
    chair's place (issue 9: geometry is never taken from a different object)."""
    now = shares_inside(grown, centers, yaws, sizes)
    return bool(np.any((now >= share) & (shares_inside(before, centers, yaws, sizes) < share)))


# A Defined box "inside" a partial one: this share of its volume in it, allowing for a few
# centimetres of noise at its edges.
PART_INSIDE_SHARE = 0.9


def part_of(det: Box, obj: Box, volume_share: float | None) -> bool:
    """True when the Defined box ``det`` is a view of a part of the partial object ``obj``: under
    ``volume_share`` of its volume and (PART_INSIDE_SHARE) inside it (None: never, the paper).

    A partial box is a lower bound of its object's extent, which a Defined box lying inside it and
    far smaller would shrink. On a four-session tum-fr1-rpy run the back of a chair, a Defined 0.55 x
    0.18 x 0.49 m object floating over the seat (12 detections, chair 0.46 / tv 0.44), merged into
    the chair of 202 detections, whose 1.04 x 0.95 x 1.11 m box (4.4 % of it) it replaced; the
    chair's own views then no longer matched it, and its id was lost."""
    if volume_share is None or not det.defined or obj.defined:
        return False
    if np.prod(det.size) >= volume_share * np.prod(obj.size):
        return False
    return bool(shares_inside(obj, det.center[None], np.array([det.yaw]), det.size[None])[0] >= PART_INSIDE_SHARE)


def integrate_box(det: Box, obj: Box, w_det: float, w_obj: float, erosion: float, min_extent: float,
                  outgrow: float | None = None, max_turn: float | None = None,
                  part_volume: float | None = None, round_footprint: bool = False) -> Box:
    """The four cases of DESIGN.md 1.3 by the Defined flags of detection i and map object j.

    ``outgrow`` (metres, None = the paper): in the two mixed cases, a partial box reaching further
    than this outside the Defined one proves the Defined box too small, and it grows along its own
    axes to cover the partial one (:func:`extended_box`). A partial view measures a lower bound of the object's
    extent; a Defined box is Defined when its vertices were visible, which a mask covering only a
    part of the object (a split mask, a couch half hidden by a table in front) also makes true: the
    paper's rule then freezes a 0.7 m piece of a 2.2 m couch against every later view.
    ``max_turn`` (radians, None = any): a partial box turned further than this against the Defined
    one (:func:`square_turn`) is not trusted to measure it: a piece of a couch seen at an angle fits
    a box turned 37 degrees whose corners reach 0.35 m past the couch's back.
    ``part_volume`` (None = the paper): a Defined detection that is a part of the partial object
    (:func:`part_of`) does not replace its box: the two enclose, as two partial views do.
    ``round_footprint`` (False = the paper): two partial boxes of a thing with no footprint
    direction enclose by :func:`round_enclosing_box`.
    """
    if det.defined and obj.defined:
        return average_boxes(det, obj, w_det, w_obj)
    if det.defined != obj.defined and outgrow is not None:
        partial, whole = (obj, det) if det.defined else (det, obj)
        if (reach_beyond(partial, whole) > outgrow
                and (max_turn is None or square_turn(partial.yaw, whole.yaw) <= max_turn)):
            return extended_box(whole, partial, erosion)
    if obj.defined:  # i partial, j Defined: a partial view cannot improve a complete box
        return Box(obj.center.copy(), obj.yaw, obj.size.copy(), obj.visible.copy(), True)
    if det.defined and not part_of(det, obj, part_volume):
        # i Defined, j partial: the complete view replaces the partial estimate
        return Box(det.center.copy(), det.yaw, det.size.copy(), det.visible.copy(), True)
    if round_footprint:
        return round_enclosing_box(det, obj, erosion, min_extent)
    return enclosing_box(det, obj, erosion, min_extent)


def merge_objects(keep: Box, drop: Box, s_keep: np.ndarray, s_drop: np.ndarray, w_keep: float, w_drop: float,
                  erosion: float, min_extent: float, outgrow: float | None = None,
                  part_volume: float | None = None, round_footprint: bool = False) -> tuple[Box, np.ndarray]:
    """Instance de-duplication: (box, class vector) of two map objects that are one.

    The box follows the four cases of :func:`integrate_box` with ``drop`` as the observation; the
    class vectors follow eq. 3 generalised to two map objects: the observation-weighted mean.
    """
    box = integrate_box(drop, keep, w_drop, w_keep, erosion, min_extent, outgrow, part_volume=part_volume,
                        round_footprint=round_footprint)
    return box, merged_scores(s_keep, s_drop, w_keep, w_drop)


def merged_scores(s_keep: np.ndarray, s_drop: np.ndarray, w_keep: float, w_drop: float) -> np.ndarray:
    """The class vector (C+1,) of two merged map objects: eq. 3 generalised, the weighted mean."""
    s = w_keep * s_keep + w_drop * s_drop
    return s / s.sum()


def stale_side(keep_current: bool, drop_current: bool) -> str | None:
    """Which box a merge of two map objects takes whole: ``"keep"`` or ``"drop"`` when only that one
    was detected in this session, None when both or neither were (then :func:`merge_objects`).

    An object last detected in an earlier session has a box that says where it *was*. When a
    detection of this session builds a second object that overlaps it enough to merge (a chair
    moved 0.3 m), the observation-weighted mean gives the old box five times the weight of the new
    one: the merged box stays on the old place (a ghost) and the chair where it is now is missed.
    The new evidence wins the box; the id of the older object stays (a moved object keeps its id).
    """
    if keep_current == drop_current:
        return None
    return "keep" if keep_current else "drop"


def stale_weight(weight: float, stale: bool, cap: float | None) -> float:
    """The weight of an object's box (or class vector) against a detection: at most ``cap`` when
    ``stale``, the object last detected in an earlier session (None: no cap). Its first detection
    of a session then moves a box that says where the object was towards where it is now (and,
    with ``integration.stale_label_weight``, re-opens a label decided by a small margin)."""
    return weight if cap is None or not stale else min(weight, float(cap))


def moved_elsewhere(det: Box, obj: Box, stale: bool) -> bool:
    """True when a partial detection says that a Defined object last detected in an earlier session
    (``stale``) now stands elsewhere: eq. 2 matched them, yet their footprints do not overlap.

    The paper keeps a Defined box against any partial view (a partial view cannot improve a
    complete box). That holds while the object stays put; a bottle put down 15 cm from where it
    stood last week matches its old object (same class, well within 0.4 m) from views that are
    partial, and its old Defined box would stay where it was, a ghost beside the bottle. A box that
    a view of the object does not even touch is no longer where the object is.
    """
    if not stale or det.defined or not obj.defined:
        return False
    iou = pairwise_ious_arrays(det.center[None], [det.yaw], det.size[None], obj.center[None], [obj.yaw],
                               obj.size[None])[0]
    return float(iou[0, 0]) <= 0.0


def confirmed_side(top_older: int, top_newer: int, older_tentative: bool, newer_tentative: bool) -> str | None:
    """Whose box a merge of two map objects keeps as it is: "older" or "newer" when their top
    classes differ and only the other one is tentative (made in this session, detected fewer times
    than confirmation needs); None otherwise (the merge's own box). That the two are one object
    under two labels is then the claim of an unconfirmed detection: its class evidence fuses (eq.
    3), its box does not reshape the confirmed one's. A one-detection Defined "chair" on a couch's
    end gave the couch its 0.64 x 0.38 m box, which its later partial views could not grow (a
    simulated house); on a reversed revisit of tum-fr1-rpy a one-detection "dining table" over the
    desk stretched a monitor's box to 1.36 x 1.33 m, which then swallowed the front monitor."""
    if top_older == top_newer or older_tentative == newer_tentative:
        return None
    return "newer" if older_tentative else "older"


def one_view_claims(made_now: np.ndarray, views: np.ndarray, min_views: int | None, n_det: np.ndarray,
                    volume: np.ndarray) -> np.ndarray:
    """(2,) bool, for the two objects of a merge (each (2,)): whether one's box is only a claim
    from one view against the other's, so that it counts as tentative for :func:`confirmed_side`:
    made in this session, detected from fewer than ``min_views`` distinct views (0: not counted;
    the confirmation rule would remove it at the session's end as it stands), fewer times than the
    other, and the larger of the two (the box a merge of dissimilar volumes takes whole).

    With a localiser's drift on tum-fr1-rpy's poses (benchmarks/bench_real.py) a "chair" 1.22 m
    tall, four detections from one view over the desk behind the front monitor, merged with the
    monitor behind it (6-21 detections) and gave it its box; the grown box then merged into the
    front monitor, and the monitor behind it was gone from 3 of the 6 drifted sessions with either
    model (drive 1's revisit lost its id).
    A merged box from two objects detected alike (two detections each: a chair's views on an oven
    in a simulated house) stays the merge's."""
    if min_views is None:
        return np.zeros(2, dtype=bool)
    made_now, views, n_det, volume = (np.asarray(a) for a in (made_now, views, n_det, volume))
    one_view = made_now & (views > 0) & (views < min_views)
    return one_view & (n_det < n_det[::-1]) & (volume > volume[::-1])


def merged_box(merged: Box, keep: Box, drop: Box, current: str | None, foreign: bool) -> Box:
    """The box of a merge: ``merged`` (:func:`merge_objects`), or the box of the one detected now
    when ``current`` names it (:func:`stale_side`); when ``foreign`` (another class, a dissimilar
    volume) the larger of the two, never the smaller one's."""
    if current is not None:
        merged = keep if current == "keep" else drop
    if foreign:
        merged = max(keep, drop, key=lambda b: float(np.prod(b.size)))
    return merged

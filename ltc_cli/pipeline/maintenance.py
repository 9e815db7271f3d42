"""Stage 4, map maintenance: which map objects should have been seen in a frame, and how much.

Pure numpy. Section 3.4 of the paper; DESIGN.md 1.4.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ltc_cli.geometry.boxes import Boxes
from ltc_cli.geometry.camera import project, transform
from ltc_cli.pipeline.visibility import occupied_pixels, pixel_counts, visible_pixels
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


class ViewCounts(NamedTuple):
    """What a frame's camera saw of each box in view, (M,) each: ``visible`` pixels, the ``needed``
    pixels for a non-detection, the ``empty`` ones (seen beyond the box's far side), the visible
    pixels for the absence rule (``visible_absent``) and of those the ones seen past the box's
    middle (``through_absent``; None when the absence rule does not ask for them), and the pixels
    the absence rule needs of a view that saw through the box (``needed_through``), and of the
    pixels counted in ``visible_absent``'s way, those where the depth has no reading (``unread``:
    zeros unless ``nondet_through_holes``)."""

    visible: np.ndarray
    needed: np.ndarray
    empty: np.ndarray
    visible_absent: np.ndarray
    through_absent: np.ndarray | None
    needed_through: np.ndarray
    unread: np.ndarray


def view_counts(boxes: Boxes, T_map_camera: np.ndarray, depth_m: np.ndarray, intr: Intrinsics,
                depth_range: tuple[float, float], m_cfg: dict) -> ViewCounts:
    """The :class:`ViewCounts` of boxes in view, by the maintenance settings ``m_cfg``:
    :func:`pixel_counts` with its hiding rules (``hidden_by_whole_box``: True for every count,
    "absence" for the absence rule's only; ``hide_needs_depth``; ``through_margin`` past the
    middle when ``absent_through_views`` or ``nondet_through_share`` is set; the unread pixels with
    ``nondet_through_holes``) and :func:`required_pixels` scaled from 640x480."""
    whole = m_cfg["hidden_by_whole_box"]
    through = m_cfg["absent_through_views"] is not None or m_cfg["nondet_through_share"] is not None
    holes = bool(m_cfg["nondet_through_holes"]) and m_cfg["nondet_through_share"] is not None
    counts = pixel_counts(
        boxes, T_map_camera, depth_m, intr, m_cfg["ray_step"], m_cfg["depth_tolerance"], depth_range,
        with_empty=True, hidden_by_whole_box=whole is True, with_whole_box=whole == "absence",
        hide_needs_depth=m_cfg["hide_needs_depth"], past_middle=m_cfg["through_margin"] if through else None,
        unread=holes)
    unread = counts[-1] if holes else np.zeros(len(boxes))
    counts = counts[:-1] if holes else counts
    vis_px, proj_px, empty_px = counts[:3]
    scale = (intr.width * intr.height) / (640 * 480)  # pixel thresholds are for 640x480
    need, need_through = (required_pixels(proj_px, m_cfg["min_visible_pixels"] * scale, m_cfg["min_visible_fraction"],
                                          m_cfg["min_pixels_floor"] * scale, share)
                          for share in (m_cfg["min_visible_share"], m_cfg["through_visible_share"]))
    vis_absent = counts[3] if whole == "absence" else vis_px
    return ViewCounts(vis_px, need, empty_px, vis_absent, counts[-1] if through else None, need_through, unread)


def stands_there(occupied_px: np.ndarray, visible_px: np.ndarray, share: float) -> np.ndarray:
    """(M,) bool: objects whose grown box holds observed depth for at least ``share`` of their
    visible pixels (:func:`~ltc_cli.pipeline.visibility.occupied_pixels`; 0 for those not asked)."""
    occupied_px = np.asarray(occupied_px, dtype=float)
    return (occupied_px > 0) & (occupied_px >= share * np.asarray(visible_px, dtype=float))


def held_by_depth(boxes: Boxes, T_map_camera: np.ndarray, depth_m: np.ndarray, intr: Intrinsics,
                  visible_px: np.ndarray, m_cfg: dict) -> np.ndarray:
    """(M,) bool: small things (footprint's longer side at most ``occupied_max_width``) that the
    depth shows standing where their box is, give or take the localiser's drift
    (``occupied_margin``; None: none). A small thing's box lies beside the thing in another view's
    frame: its rays pass the thing and look "seen through" while the thing's own surface still
    ends within a few centimetres of the box. Neither a miss (eq. 4) nor the absence rule's "seen
    through" counts for them. Depth past the box's middle by ``through_margin`` is where the rays
    that saw through it end (a wall the box touches), not the thing. Larger things overlap their
    boxes whatever the drift, and their neighbours (a table behind a chair) stand within the margin."""
    if m_cfg["occupied_margin"] is None or len(boxes) == 0:
        return np.zeros(len(boxes), dtype=bool)
    small = np.flatnonzero(boxes.size[:, :2].max(axis=1) <= m_cfg["occupied_max_width"])
    occupied = np.zeros(len(boxes))
    occupied[small] = occupied_pixels(boxes.take(small), T_map_camera, depth_m, intr, m_cfg["ray_step"],
                                      m_cfg["occupied_margin"], m_cfg["occupied_lift"], m_cfg["through_margin"])
    return stands_there(occupied, visible_px, m_cfg["occupied_share"])


def standing_in_box(boxes: Boxes, T_map_camera: np.ndarray, depth_m: np.ndarray, intr: Intrinsics,
                    depth_range: tuple[float, float], m_cfg: dict, share: float) -> np.ndarray:
    """(M,) bool: boxes whose visible pixels' observed depth ends inside them (their bottom raised
    by ``occupied_lift``, not past their middle by ``through_margin``) for at least ``share`` of
    those pixels: the depth shows the thing standing in its own box, no drift margin given."""
    if len(boxes) == 0:
        return np.zeros(0, dtype=bool)
    step = m_cfg["ray_step"]
    visible = visible_pixels(boxes, T_map_camera, depth_m, intr, step, m_cfg["depth_tolerance"], depth_range)
    occupied = occupied_pixels(boxes, T_map_camera, depth_m, intr, step, 0.0, m_cfg["occupied_lift"],
                               m_cfg["through_margin"])
    return stands_there(occupied, visible, share)


def count_absence_views(cols: dict, rows: np.ndarray, clear_absent: np.ndarray, matched: np.ndarray,
                        seen_through: np.ndarray, session: int) -> None:
    """Add one frame's views to the absence rule's counts of the in-view ``rows`` (updates the
    object columns ``cols`` in place): clear views in this session (``clear_session`` holds the
    session + 1; 0: none yet, maps from before), clear views without a detection since the last
    detection (``clear_since_det``), and of those the ones that saw through the box
    (``through_since_det``). clear_absent, matched, seen_through: (M,) bool over rows."""
    fresh = rows[clear_absent & (cols["clear_session"][rows] != session + 1)]
    cols["clear_session"][fresh], cols["clear_in_session"][fresh] = session + 1, 0
    cols["clear_in_session"][rows[clear_absent]] += 1
    cols["clear_since_det"][rows[clear_absent & ~matched]] += 1
    cols["through_since_det"][rows[clear_absent & ~matched & seen_through]] += 1


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


def other_outweighs(scores: np.ndarray) -> np.ndarray:
    """(M,) bool: objects whose `other` (last) entry exceeds all their classes (M, C+1) together:
    the evidence says the thing is not there, not only that its leading label lost ground (a sink
    the detector also calls toilet holds its evidence on two labels, and eq. 4's `other` overtakes
    each of them long before both)."""
    scores = np.atleast_2d(scores)
    return scores[:, -1] > scores[:, :-1].sum(axis=1)


def class_hit_counts(top: np.ndarray, n_clear: np.ndarray, n_clear_det: np.ndarray, n_classes: int):
    """(views (C,), hits (C,)) summed over objects by their top class: the frames in which each was
    clearly visible, and those of them in which it was detected."""
    views = np.bincount(top, weights=n_clear, minlength=n_classes).astype(np.int64)
    hits = np.bincount(top, weights=n_clear_det, minlength=n_classes).astype(np.int64)
    return views, hits


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


def removed_unconfirmed(status: np.ndarray, first_session: np.ndarray, last_session: np.ndarray, weak: np.ndarray,
                        session: int, removed: int) -> np.ndarray:
    """(N,) bool: objects an earlier session removed as unconfirmed: status ``removed``, detected
    only in the session that made them, before ``session``, on evidence the confirmation rule finds
    too weak (``weak`` (N,), :func:`unconfirmed` on their columns as they were removed)."""
    return (status == removed) & (first_session == last_session) & (last_session < session) & weak


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


def hole_shares(visible_px: np.ndarray, unread_px: np.ndarray) -> np.ndarray:
    """(M,) the share of each box's unhidden pixels in range where the depth has no reading."""
    visible_px, unread_px = np.asarray(visible_px, float), np.asarray(unread_px, float)
    total = visible_px + unread_px
    return np.divide(unread_px, total, out=np.zeros(len(total)), where=total > 0)


def own_holes(det_holes: np.ndarray, n_clear_det: np.ndarray, min_share: float | None) -> np.ndarray:
    """(M,) bool: objects whose box, in the clear views that detected them, had on average at least
    ``min_share`` of its pixels without depth (:func:`hole_shares`): the holes are the thing's own
    (a dark screen), so holes where it stands are no evidence that its place is empty. None: none."""
    n = np.asarray(n_clear_det, float)
    if min_share is None:
        return np.zeros(len(n), dtype=bool)
    return (n > 0) & (np.asarray(det_holes, float) >= min_share * n)


def absent_in_session(active: np.ndarray, first_session: np.ndarray, last_session: np.ndarray,
                      clear_session: np.ndarray, clear_in_session: np.ndarray, session: int, views,
                      clear_since_det: np.ndarray | None = None, quiet_sessions: int | None = None,
                      quiet_views: int | None = None, through_since_det: np.ndarray | None = None,
                      empty_views: int | None = None) -> np.ndarray:
    """(M,) bool: active objects of earlier sessions seen clearly in at least ``views`` frames of
    this session (a number, or (M,) per object; inf: never by one session) and detected in none: a
    whole visit's worth of views, not one unlucky frame (``clear_session`` holds the session of the
    clear views + 1, 0 for none yet).

    With ``quiet_sessions`` (and ``clear_since_det``: clear views without a detection since the
    last detection, over sessions), also those not detected in the last ``quiet_sessions``
    sessions (this one included) whose clear views since their last detection reach ``quiet_views``
    (None: ``views``): a
    chair taken away whose old place each lap sees clearly only two or three times (the room's far
    corner) is as gone after two laps as one seen five times in one.

    With ``empty_views`` (and ``through_since_det``: those clear views without a detection that saw
    through the box), the session's count removes only objects whose place the camera saw empty
    in at least that many views: one pass of the detector's silence is not enough when the depth
    still shows something there (a tv or a book missed for a whole pass, in a run of correlated
    misses). Silence over ``quiet_sessions`` whole sessions stays enough.
    """
    quiet = np.asarray(active) & (np.asarray(first_session) < session) & (np.asarray(last_session) < session)
    gone = (np.asarray(clear_session) == session + 1) & (np.asarray(clear_in_session) >= views)
    if empty_views is not None and through_since_det is not None:
        gone &= np.asarray(through_since_det) >= empty_views
    if quiet_sessions is not None and clear_since_det is not None:
        gone |= ((np.asarray(last_session) <= session - quiet_sessions)
                 & (np.asarray(clear_since_det) >= (views if quiet_views is None else quiet_views)))
    return quiet & gone

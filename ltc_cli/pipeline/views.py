"""Distinct views of detection, for the confirmation rule (``maintenance.min_detection_views``) and
for counting non-detections from new views only: where the camera stood and looked when it saw or
missed an object. Pure numpy.
"""

from __future__ import annotations

import numpy as np


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


# The directions along which an object's detection views are spread (span_views), for the camera
# positions and the forward axes alike: x, y, z and the two horizontal diagonals (a spread along
# any horizontal direction shows along one of these to within cos 22.5 degrees, 92 %).
SPAN_AXES = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [0.5 ** 0.5, 0.5 ** 0.5, 0], [0.5 ** 0.5, -(0.5 ** 0.5), 0]])
SPAN_SIZE = 4 * len(SPAN_AXES)


def _span_coords(view: np.ndarray) -> np.ndarray:
    return np.concatenate([SPAN_AXES @ view[:3], SPAN_AXES @ view[3:]])


def widen_span(span: np.ndarray, view: np.ndarray, empty: bool) -> np.ndarray:
    """The span (SPAN_SIZE,) of an object's detection views, the least then the greatest of each
    coordinate (the camera position along SPAN_AXES, then the forward axis along them), with one more
    view (6,) (camera_view); ``empty``: no view yet."""
    c = _span_coords(view)
    one = np.concatenate([c, c])  # the span of this view alone
    return one if empty else union_span(span, one)


def union_span(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The span (..., SPAN_SIZE) of the views of two spans (widen_span), both holding views."""
    n = a.shape[-1] // 2
    return np.concatenate([np.minimum(a[..., :n], b[..., :n]), np.maximum(a[..., n:], b[..., n:])], axis=-1)


def span_views(spans: np.ndarray, counted: np.ndarray, min_move: float | None, min_turn_deg: float | None) -> np.ndarray:
    """(M,) distinct views of detection by the spans (M, SPAN_SIZE): 2 where the camera positions
    spread ``min_move`` metres along one of SPAN_AXES or the forward axes by the chord of
    ``min_turn_deg`` along one, else 1; ``counted`` (M,) (the views counted one after another)
    where it is 0 (none) or the span is all zeros (made before ltc kept spans).

    Counting a view when the camera has moved or turned enough since the last counted one depends
    on the order of the frames: on tum-fr1-rpy two stacks of papers called "book" in 3-4 frames
    got their second view in reverse order and not forward. Whether two of an object's views lie
    that far apart along one direction does not depend on the order."""
    spans = np.atleast_2d(np.asarray(spans, dtype=np.float64))
    counted = np.asarray(counted)
    n = spans.shape[1] // 2
    k = len(SPAN_AXES)
    extent = spans[:, n:] - spans[:, :n]
    wide = np.zeros(len(spans), dtype=bool)
    if min_move is not None:
        wide |= extent[:, :k].max(axis=1) >= min_move
    if min_turn_deg is not None:
        wide |= extent[:, k:].max(axis=1) >= 2 * np.sin(np.radians(min_turn_deg) / 2)
    known = (counted > 0) & spans.any(axis=1)
    return np.where(known, np.where(wide, 2, 1), counted)


def views_apart(spans_a: np.ndarray, spans_b: np.ndarray, min_move: float | None,
                min_turn_deg: float | None) -> np.ndarray:
    """(K,) bool: whether the views of two spans (K, SPAN_SIZE) each, taken together, are two
    distinct views (:func:`span_views`): an object seen from one view in each of two sessions, from
    places ``min_move`` metres or directions ``min_turn_deg`` degrees apart."""
    both = union_span(np.atleast_2d(spans_a), np.atleast_2d(spans_b))
    return span_views(both, np.full(len(both), 2), min_move, min_turn_deg) >= 2

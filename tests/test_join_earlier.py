"""maintenance.earlier_overlap_iou (issue 9, thirty-seventh round): at a session's end, a confirmed
new object whose footprint overlaps an earlier session's object of its class merges into it, which
keeps its id and its box (one thing seen in two drives, off by the localiser's drift between them).
Two small ones join at a lower bar, maintenance.earlier_small_overlap_iou (thirty-ninth round).
Expected values by hand."""

import numpy as np
import pytest

from ltc_cli.config import defaults
from ltc_cli.map.model import ACTIVE, MERGED, REMOVED, SemanticMap
from ltc_cli.pipeline.rejoining import earlier_duplicates, join_bars
from tests.test_reidentify import CLASSES, CUP, MOUSE, row_boxes
from tests.session_end import end_session


def test_earlier_duplicates_by_hand():
    # 0.1 x 0.1 footprints. A new mouse at x 0 and earlier ones at x 0.05 (overlap 0.05 x 0.1 =
    # 0.005 m², union 0.015: IoU 1/3) and 0.11 (apart: 0), and a cup on the same ground (IoU 1).
    new, top = row_boxes([0.0]), np.array([MOUSE])
    earlier, earlier_top = row_boxes([0.11, 0.05, 0.0]), np.array([MOUSE, MOUSE, CUP])
    pairs = earlier_duplicates(new, top, earlier, earlier_top, 0.1)
    assert [(k, j) for k, j, _ in pairs] == [(0, 1)]
    assert pairs[0][2] == pytest.approx(1 / 3)
    assert earlier_duplicates(new, top, earlier, earlier_top, 0.34) == []
    # Boxes 0.01 m apart share nothing, however low the bar.
    assert earlier_duplicates(new, top, row_boxes([0.11]), np.array([MOUSE]), 1e-6) == []
    # One pair each, greatest overlap first: new mice at x 0 and 0.02 over one earlier mouse at x 0
    # (IoU 1, and 0.08 x 0.1 / 0.012 = 2/3): only the first; a second earlier mouse at x 0.1 then
    # takes the one at 0.02 (0.02 x 0.1 / 0.018 = 1/9).
    two = row_boxes([0.0, 0.02])
    pairs = earlier_duplicates(two, np.array([MOUSE, MOUSE]), row_boxes([0.0]), np.array([MOUSE]), 0.1)
    assert [(k, j) for k, j, _ in pairs] == [(0, 0)]
    pairs = earlier_duplicates(two, np.array([MOUSE, MOUSE]), row_boxes([0.0, 0.1]), np.array([MOUSE, MOUSE]), 0.1)
    assert [(k, j) for k, j, _ in pairs] == [(0, 0), (1, 1)]
    assert pairs[1][2] == pytest.approx(1 / 9)


def test_join_bars_by_hand():
    # Longer sides 0.1 and 0.25 m are small (at most 0.25), 0.3 m is not: the lower bar only where
    # both of a pair are small.
    new = np.array([[0.1, 0.05, 0.05], [0.3, 0.1, 0.5]])
    old = np.array([[0.25, 0.2, 0.1], [0.05, 0.3, 0.1], [0.1, 0.1, 0.1]])
    np.testing.assert_allclose(join_bars(new, old, 0.1, 0.02, 0.25), [[0.02, 0.1, 0.02], [0.1, 0.1, 0.1]])
    np.testing.assert_allclose(join_bars(new, old, 0.1, None, 0.25), np.full((2, 3), 0.1))


def test_earlier_duplicates_with_a_bar_per_pair():
    # New mice at x 0 and 0.2 over earlier ones at x 0.09 and 0.29: IoU 0.01 x 0.1 / 0.019 = 1/19
    # each. A bar of 0.05 joins the first pair only, and (1/19 >= 0.05) only where the bar says so.
    new, earlier, mice = row_boxes([0.0, 0.2]), row_boxes([0.09, 0.29]), np.array([MOUSE, MOUSE])
    pairs = earlier_duplicates(new, mice, earlier, mice, np.array([[0.05, 0.05], [0.1, 0.1]]))
    assert [(k, j) for k, j, _ in pairs] == [(0, 0)]
    assert pairs[0][2] == pytest.approx(1 / 19)
    assert len(earlier_duplicates(new, mice, earlier, mice, np.full((2, 2), 0.05))) == 2


def session_end(min_iou=0.1, new_x=0.05, new_class=MOUSE, new_det=5, small_iou=None, width=0.1):
    """Session 1's end: row 0 a mouse made in session 0 (8 detections) at x 0, ``width`` x ``width``
    x 0.05 m, detected in session 1 too, last at frame 30 (the absence rule keeps it); row 1 made in
    session 1 at ``new_x``, the same size (``new_det`` detections from 2 views in 10 clear frames,
    the last at frame 35). ``small_iou``: ``earlier_small_overlap_iou`` (None: off)."""
    cfg = defaults()
    cfg["maintenance"]["earlier_overlap_iou"] = min_iou
    cfg["maintenance"]["earlier_small_overlap_iou"] = small_iou
    smap = SemanticMap.new(CLASSES)
    t = smap.objects
    for x, cls, n_det, session in ((0.0, MOUSE, 8, 0), (new_x, new_class, new_det, 1)):
        v = np.full(len(CLASSES) + 1, 0.05)
        v[cls], v[-1] = 0.9, 0.0
        t.append(center=np.array([x, 0.0, 0.75]), yaw=0.0, size=np.array([width, width, 0.05]), scores=v, n_det=n_det,
                 n_clear=10, det_views=2, status=ACTIVE, first_session=session, first_frame=20 * session,
                 last_session=1, last_frame=30 + 5 * session, clear_session=2, clear_in_session=10)
    return end_session(smap, cfg)


def test_the_earlier_object_takes_the_new_one_and_keeps_its_box():
    smap = session_end()
    t = smap.objects
    assert (t.status[0], t.status[1]) == (ACTIVE, MERGED)
    np.testing.assert_allclose(t.center[0], [0.0, 0.0, 0.75])
    np.testing.assert_allclose(t.size[0], [0.1, 0.1, 0.05])
    # Last detected at the new one's last frame (35), not at the session's end (-1).
    assert (t.n_det[0], t.first_session[0], t.last_session[0], t.last_frame[0]) == (13, 0, 1, 35)
    kinds = [(e.kind, e.object_id, e.other_id) for e in smap.events if e.session == 1 and e.frame == -1]
    assert kinds == [("updated", 1, 0), ("merged", 1, 2)]
    assert next(e.detail for e in smap.events if e.kind == "updated") == (
        "joined: object 2 of this session, 5 detections of its class, overlaps its box (XY IoU 0.33) and is it")


@pytest.mark.parametrize("change, new_status", [
    ({"min_iou": None}, ACTIVE),        # the paper
    ({"new_x": 0.09}, ACTIVE),          # 0.01 x 0.1 / 0.019: IoU 0.053 < 0.1
    ({"new_class": CUP}, ACTIVE),       # another class on the same ground
    ({"new_det": 1}, REMOVED),          # unconfirmed: it goes as such
    ({"new_x": 0.02, "min_iou": 0.7}, ACTIVE),   # IoU 2/3 < 0.7
])
def test_no_join(change, new_status):
    smap = session_end(**change)
    t = smap.objects
    assert (t.status[0], t.status[1]) == (ACTIVE, new_status)
    assert not any(e.detail.startswith("joined") for e in smap.events)


def test_a_greater_overlap_joins_at_a_higher_bar():
    smap = session_end(new_x=0.02, min_iou=0.6)  # IoU 2/3 >= 0.6
    assert smap.objects.status[1] == MERGED


@pytest.mark.parametrize("change, joined", [
    ({"new_x": 0.09, "small_iou": 0.02}, True),                 # IoU 1/19 >= 0.02, both 0.1 m
    ({"new_x": 0.099, "small_iou": 0.02}, False),               # 0.001 x 0.1 / 0.0199: IoU 0.005
    ({"new_x": 0.45, "width": 0.5, "small_iou": 0.02}, False),  # IoU 0.05 / 0.95 = 1/19, 0.5 m: not small
    ({"new_x": 0.25, "width": 0.26, "small_iou": 0.02}, False),  # 0.01 / 0.51: 1/51, but 0.26 m: not small
    ({"new_x": 0.24, "width": 0.25, "small_iou": 0.02}, True),   # 0.01 / 0.49: 1/49 >= 0.02, 0.25 m
    ({"new_x": 0.09, "small_iou": 0.02, "min_iou": None}, False),  # the join is off altogether
])
def test_two_small_things_join_at_the_lower_bar(change, joined):
    smap = session_end(**change)
    assert smap.objects.status[1] == (MERGED if joined else ACTIVE)
    assert any(e.detail.startswith("joined") for e in smap.events) == joined

"""maintenance.reidentify_margin (issue 9, thirty-sixth round): at a session's end, an object of an
earlier session that the session saw clearly and never detected takes, with its id, the confirmed
new object of its class just beside it (a robot's localiser off in another way on this drive).
Expected values by hand."""

import numpy as np
import pytest

from ltc_cli.config import defaults
from ltc_cli.geometry.boxes import Boxes
from ltc_cli.map.model import ACTIVE, MERGED, REMOVED, SemanticMap
from ltc_cli.pipeline.rejoining import drifted_match
from tests.session_end import end_session
CLASSES = ["mouse", "cup", "keyboard"]
MOUSE, CUP = 0, 1


def row_boxes(xs, width=0.1):
    """Axis-aligned boxes width x width x 0.05 m centred at (x, 0, 0.75)."""
    n = len(xs)
    return Boxes(np.c_[xs, np.zeros(n), np.full(n, 0.75)], np.zeros(n), np.tile([width, width, 0.05], (n, 1)),
                 np.ones((n, 8), bool))


def test_drifted_match_by_hand():
    new = row_boxes([0.0])
    # Earlier objects at x 0.15 (footprint gap 0.05), 0.3 (gap 0.2) and a cup at 0.12 (gap 0.02).
    earlier, earlier_top = row_boxes([0.3, 0.15, 0.12]), np.array([MOUSE, MOUSE, CUP])
    none = row_boxes([])
    assert drifted_match(new, np.array([MOUSE]), earlier, earlier_top, none, np.zeros(0, int), 0.08).tolist() == [1]
    assert drifted_match(new, np.array([MOUSE]), earlier, earlier_top, none, np.zeros(0, int), 0.04).tolist() == [-1]
    # A cup finds the cup (gap 0.02).
    assert drifted_match(new, np.array([CUP]), earlier, earlier_top, none, np.zeros(0, int), 0.04).tolist() == [2]
    # Another mouse of the map 0.03 away on the other side (x -0.13) is nearer than the 0.05: none;
    # one 0.07 away (x -0.17) is not.
    for x, expected in ((-0.13, -1), (-0.17, 1)):
        got = drifted_match(new, np.array([MOUSE]), earlier, earlier_top, row_boxes([x]), np.array([MOUSE]), 0.08)
        assert got.tolist() == [expected], x
    # A cup there is no rival for a mouse.
    assert drifted_match(new, np.array([MOUSE]), earlier, earlier_top, row_boxes([-0.13]), np.array([CUP]),
                         0.08).tolist() == [1]


def session_end(margin=0.08, new_x=0.15, old_seen=True, old_detected=False, new_det=5, seen_empty=20):
    """Session 1's end over two mice: row 0 made in session 0 (8 detections) at x 0, seen clearly in
    20 frames of session 1 (``old_seen``; its place seen empty in ``seen_empty`` of them) and, with
    ``old_detected``, detected in it; row 1 made in
    session 1 at ``new_x`` (``new_det`` detections from 2 views in 10 clear frames)."""
    cfg = defaults()
    cfg["maintenance"]["reidentify_margin"] = margin
    smap = SemanticMap.new(CLASSES)
    t = smap.objects
    v = np.array([0.9, 0.05, 0.05, 0.0])  # mouse, cup, keyboard, other
    t.append(center=np.array([0.0, 0.0, 0.75]), yaw=0.0, size=np.array([0.1, 0.1, 0.05]), scores=v, n_det=8,
             status=ACTIVE, first_session=0, last_session=1 if old_detected else 0, det_views=2,
             clear_session=2 if old_seen else 1, clear_in_session=20 if old_seen else 0,
             clear_since_det=0 if old_detected else 20, through_since_det=0 if old_detected else seen_empty)
    t.append(center=np.array([new_x, 0.0, 0.75]), yaw=0.0, size=np.array([0.1, 0.12, 0.06]), scores=v,
             n_det=new_det, n_clear=10, det_views=2, status=ACTIVE, first_session=1, first_frame=20,
             last_session=1, last_frame=30)
    return end_session(smap, cfg)


def test_the_old_object_takes_the_new_one_with_its_id():
    smap = session_end()
    t = smap.objects
    assert (t.status[0], t.status[1]) == (ACTIVE, MERGED)
    # The box this session saw; the counts of both; detected in this session now.
    np.testing.assert_allclose(t.center[0], [0.15, 0.0, 0.75])
    np.testing.assert_allclose(t.size[0], [0.1, 0.12, 0.06])
    assert (t.n_det[0], t.first_session[0], t.last_session[0], t.last_frame[0]) == (13, 0, 1, 30)
    kinds = [(e.kind, e.object_id, e.other_id) for e in smap.events if e.session == 1 and e.frame == -1]
    assert kinds == [("updated", 1, 0), ("merged", 1, 2)]
    assert next(e.detail for e in smap.events if e.kind == "updated").startswith(
        "re-identified: not detected at its box in this session, and object 2, 5 detections")


@pytest.mark.parametrize("change", [
    {"margin": None},  # the paper
    {"new_x": 0.3},  # footprint gap 0.2 m
    {"old_seen": False},  # this session never saw the old one's place clearly
    {"old_detected": True},  # detected in this session: the new one is another thing beside it
    {"new_det": 1},  # the new one is unconfirmed
    {"seen_empty": 1},  # its place seen empty once (absent_through_views 2): the absence rule keeps it
])
def test_no_reidentification(change):
    smap = session_end(**change)
    t = smap.objects
    assert t.status[1] != MERGED
    assert not any(e.detail.startswith("re-identified") for e in smap.events)
    if change == {"margin": None}:
        # Without the rule the old mouse goes as absent and the new one stays: the id is lost.
        assert (t.status[0], t.status[1]) == (REMOVED, ACTIVE)

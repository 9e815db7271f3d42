"""maintenance.session_overlap_iou (issue 9, thirty-eighth round): at a session's end, two
confirmed small objects of one class made in it whose footprints overlap become one, the better
seen keeping its id and its box (a jittery localiser's copies of one small thing within a drive).
Expected values by hand."""

import numpy as np
import pytest

from ltc_cli.config import defaults
from ltc_cli.map.model import ACTIVE, MERGED, SemanticMap
from ltc_cli.pipeline.rejoining import earlier_duplicates
from tests.test_reidentify import CLASSES, CUP, MOUSE, row_boxes
from tests.session_end import end_session


def test_one_set_against_itself_by_hand():
    # 0.1 x 0.1 footprints at x 0, 0.05 and 0.1, best seen first: 0 and 1 overlap by 0.05 x 0.1 =
    # 0.005 m² of a 0.015 m² union (IoU 1/3), 1 and 2 too, 0 and 2 touch (0). The later one of the
    # first pair goes into the earlier; 1 is then taken, so 2 stays.
    three, top = row_boxes([0.0, 0.05, 0.1]), np.array([MOUSE] * 3)
    pairs = earlier_duplicates(three, top, three, top, 0.1, same=True)
    assert [(k, j) for k, j, _ in pairs] == [(1, 0)]
    assert pairs[0][2] == pytest.approx(1 / 3)
    # Another class on the same ground, or a bar over 1/3: nothing.
    cup = np.array([MOUSE, CUP, MOUSE])
    assert [(k, j) for k, j, _ in earlier_duplicates(three, cup, three, cup, 0.1, same=True)] == []
    assert earlier_duplicates(three, top, three, top, 0.34, same=True) == []


def session_end(min_iou=0.1, x=0.05, size=0.1, n_det=(9, 13), first=(0, 1)):
    """Session 1's end over two confirmed mice made in session ``first`` each (``n_det``
    detections, 2 views, 10 clear frames): row 0 at x 0, last detected at frame 40; row 1 at
    ``x``, last at frame 30; both ``size`` x ``size`` x 0.05 m."""
    cfg = defaults()
    cfg["maintenance"]["session_overlap_iou"] = min_iou
    cfg["maintenance"]["earlier_overlap_iou"] = None  # this test is of the join within the session
    smap = SemanticMap.new(CLASSES)
    v = np.full(len(CLASSES) + 1, 0.05)
    v[MOUSE], v[-1] = 0.9, 0.0
    for cx, n, last, s in ((0.0, n_det[0], 40, first[0]), (x, n_det[1], 30, first[1])):
        smap.objects.append(center=np.array([cx, 0.0, 0.75]), yaw=0.0, size=np.array([size, size, 0.05]), scores=v,
                            n_det=n, n_clear=10, det_views=2, status=ACTIVE, first_session=s, first_frame=10,
                            last_session=1, last_frame=last, clear_session=2, clear_in_session=10)
    return end_session(smap, cfg)


def test_the_better_seen_keeps_its_id_and_box():
    """Both made in session 1: row 1 (13 detections) keeps its box at x 0.05 and takes row 0's 9
    detections; the last frame is the later of the two (40)."""
    smap = session_end(first=(1, 1))
    t = smap.objects
    assert (t.status[0], t.status[1]) == (MERGED, ACTIVE)
    np.testing.assert_allclose(t.center[1], [0.05, 0.0, 0.75])
    assert (t.n_det[1], t.last_frame[1]) == (22, 40)
    assert next(e.detail for e in smap.events if e.kind == "updated") == (
        "joined: object 1 of this session, 9 detections of its class, overlaps its box (XY IoU 0.33) and is it")


@pytest.mark.parametrize("change", [
    {"min_iou": None},           # the paper
    {"x": 0.09},                 # 0.01 x 0.1 / 0.019: IoU 0.053 < 0.1
    {"size": 0.3, "x": 0.15},    # furniture-sized (0.3 m > occupied_max_width 0.25): IoU 1/3, left alone
    {"first": (0, 1)},           # one of them an earlier session's: earlier_overlap_iou's (off here)
    {"x": 0.099, "min_iou": 0.02},  # 0.001 x 0.1 / 0.0199: IoU 0.005 < 0.02 (the default since round 39)
])
def test_no_join_within(change):
    smap = session_end(**{"first": (1, 1), **change})
    t = smap.objects
    assert (t.status[0], t.status[1]) == (ACTIVE, ACTIVE)


def test_the_default_bar_joins_a_sliver_of_shared_ground():
    """At the default bar (0.02, thirty-ninth round) two mice made in session 1 that share 0.01 x
    0.1 m of ground (IoU 1/19 = 0.053, under the thirty-eighth round's 0.1) become one."""
    assert defaults()["maintenance"]["session_overlap_iou"] == 0.02
    smap = session_end(min_iou=0.02, x=0.09, first=(1, 1))
    assert (smap.objects.status[0], smap.objects.status[1]) == (MERGED, ACTIVE)

"""The rules against ghosts that pile up over laps (docs/decisions.md, issue 9, third round): a merge
of an object found now with one last seen in an earlier session takes the box found now, and a box
hides another only when it lies wholly in front of it. Expected values worked out by hand."""

import numpy as np
import pytest

from ltc_cli import plugins
from ltc_cli.config import defaults
from ltc_cli.geometry.boxes import Boxes
from ltc_cli.map.model import ACTIVE, MERGED, REMOVED, SemanticMap
from ltc_cli.geometry.boxes import Box
from ltc_cli.pipeline.integration import stale_side, stale_weight
from ltc_cli.pipeline.maintenance import absent_in_session
from ltc_cli.pipeline.visibility import pixel_counts
from ltc_cli.pipeline.mapper import Mapper
from tests.scene import INTR, T_world_camera, render
from tests.test_accuracy_rules import every_miss_counts
from tests.test_identity import CHAIR_BOX, CHAIR_FACE, CLASSES, chair_vector


def one_empty_frame(smap, cfg, rows, session=1):
    """A mapper of ``session`` over the map's ``rows`` (indexed), and one frame with nothing detected
    and nothing in front of the wall 4 m away."""
    mapper = Mapper(smap, cfg, plugins.get("metrics", "vertex").factory(cfg["association"]),
                    plugins.get("policies", "non-detection").factory(cfg["maintenance"]), session=session)
    for r in rows:
        mapper.index.insert(r, smap.objects.center[r], smap.objects.size[r])
    empty, _ = render([], wall_x=4.0)
    mapper.process_frame(0, "0", [], [], empty, T_world_camera(), INTR, (0.3, 6.0))
    return mapper


def test_stale_side_by_hand():
    assert stale_side(True, False) == "keep"
    assert stale_side(False, True) == "drop"
    assert stale_side(True, True) is None
    assert stale_side(False, False) is None


@pytest.mark.parametrize("rule, last_sessions, expected_y, expected_sy", [
    (True, (0, 1), 0.7, 1.0),    # the old chair (id 1) keeps its id, the box found now wins
    (False, (0, 1), 0.35, 1.1),  # the paper: the observation-weighted mean (weights 5 and 5)
    (True, (1, 1), 0.35, 1.1),   # both found in this session: the mean, as before
])
def test_a_merge_with_a_stale_object_takes_the_box_found_now(rule, last_sessions, expected_y, expected_sy):
    """Chair A of session 0 (0.4 x 1.2 m at y 0) and chair B built in session 1 (0.4 x 1.0 at y 0.7):
    0.4 of B's volume lies inside A, over merge_containment 0.3, so they merge after a frame of
    session 1 (A, the older id, keeps). Both Defined with 20 detections (weight cap 5 each): the
    mean has y (0 + 0.7) / 2 = 0.35 and length (1.2 + 1.0) / 2 = 1.1; B's box is y 0.7, length 1.0."""
    cfg = every_miss_counts(defaults())
    cfg["association"]["merge_current_box"] = rule
    smap = SemanticMap.new(CLASSES)
    t = smap.objects
    rows = [t.append(center=[2.2, y, 0.6], yaw=0.0, size=[0.4, sy, 0.8], visible=np.ones(8, bool), defined=True,
                     scores=chair_vector(), n_det=20, status=ACTIVE, first_session=first, last_session=last)
            for y, sy, first, last in ((0.0, 1.2, 0, last_sessions[0]), (0.7, 1.0, 1, last_sessions[1]))]
    one_empty_frame(smap, cfg, rows)
    assert (t.status[rows[0]], t.status[rows[1]]) == (ACTIVE, MERGED)
    assert t.center[rows[0]][1] == pytest.approx(expected_y, abs=1e-6)
    assert t.size[rows[0]][1] == pytest.approx(expected_sy, abs=1e-6)


def boxes(*rows):
    """Axis-aligned Boxes from (x0, x1, y0, y1, z0, z1) rows."""
    a = np.array(rows, dtype=float)
    centers = np.stack([a[:, 0] + a[:, 1], a[:, 2] + a[:, 3], a[:, 4] + a[:, 5]], axis=1) / 2
    sizes = np.stack([a[:, 1] - a[:, 0], a[:, 3] - a[:, 2], a[:, 5] - a[:, 4]], axis=1)
    return Boxes(centers, np.zeros(len(a)), sizes, np.ones((len(a), 8), bool))


CUP = (2.0, 2.2, -0.1, 0.1, 0.9, 1.1)      # its face: 0.2 x 0.2 m at 2 m: 50 x 50 px at f 500
TABLE = (1.5, 2.7, -0.8, 0.8, 0.3, 1.15)   # a loose table box around the cup
CHAIR = (1.0, 1.3, -0.3, 0.3, 0.5, 1.5)    # a box wholly in front of the cup


@pytest.mark.parametrize("whole_box", [True, False])
def test_a_cup_inside_a_table_box_is_visible_when_boxes_hide_only_what_lies_behind_them(whole_box):
    """Depth: the cup's face at 2 m, a wall at 4 m. Every ray to the cup enters the table's box
    first (x 1.5) but leaves it only at x 2.7, beyond the cup's face: the entry rule (the paper)
    hides the whole cup, the whole-box rule hides none of it, 50 x 50 = 2500 px (sampled by one ray
    per 2 x 2 block: within 10 %)."""
    depth, _ = render([CUP], wall_x=4.0)
    vis, proj = pixel_counts(boxes(CUP, TABLE), T_world_camera(), depth, INTR, 2, 0.2, (0.3, 6.0),
                             hidden_by_whole_box=whole_box)
    assert proj[0] == pytest.approx(2500, rel=0.1)
    assert vis[0] == (pytest.approx(2500, rel=0.1) if whole_box else 0)


@pytest.mark.parametrize("whole_box", [True, False])
def test_a_box_wholly_in_front_still_hides(whole_box):
    """The chair's box ends at x 1.3, before the cup (2.0) and the table (1.5): it hides the cup's
    rays (all of which pass through it: |y| <= 0.065, |z - 1| <= 0.065 at x 1.0-1.3) either way."""
    depth, _ = render([CUP], wall_x=4.0)
    vis, _ = pixel_counts(boxes(CUP, TABLE, CHAIR), T_world_camera(), depth, INTR, 2, 0.2, (0.3, 6.0),
                          hidden_by_whole_box=whole_box)
    assert vis[0] == 0


@pytest.mark.parametrize("chair_there, needs_depth, expected_share", [
    (False, False, 0.0),        # the chair's box hides the cup's place, whatever the depth says
    (False, True, 1.0),         # the depth reaches 2 m, past the box's far side (1.3 + 0.2): not hidden
    (False, "absence", 0.0),    # ...for the absence rule's count only
    (True, True, 0.0),          # the chair is there (its face at 1.0 m): it hides the cup
])
def test_a_box_hides_only_where_the_depth_ends_in_it(chair_there, needs_depth, expected_share):
    """The chair's box (x 1.0-1.3) lies wholly in front of the cup (face at 2 m). When the depth
    shows the cup's face through it (the chair was a coarse box, or is gone), the box hides nothing
    with hide_needs_depth; when the chair's face is at 1.0 m, it hides the cup either way. The
    whole-box count (last) follows "absence" as well as True."""
    depth, _ = render([CUP, CHAIR] if chair_there else [CUP], wall_x=4.0)
    vis, proj, vis_whole = pixel_counts(boxes(CUP, CHAIR), T_world_camera(), depth, INTR, 2, 0.2, (0.3, 6.0),
                                        with_whole_box=True, hide_needs_depth=needs_depth)
    assert proj[0] == pytest.approx(2500, rel=0.1)
    assert vis[0] == pytest.approx(expected_share * proj[0])
    assert vis_whole[0] == pytest.approx((0.0 if chair_there or not needs_depth else 1.0) * proj[0])


@pytest.mark.parametrize("quiet, detect_in_session_2, expected", [
    (2, False, REMOVED),     # 3 + 3 = 6 clear views since its last detection >= 5, two sessions quiet
    (None, False, ACTIVE),   # 3 < 5 in each session
    (3, False, ACTIVE),      # not yet three sessions without a detection
    (1, True, ACTIVE),       # detected in session 2: counted from 0 again (2 clear views since)
])
def test_clear_views_since_the_last_detection_add_up_over_quiet_sessions(quiet, detect_in_session_2, expected):
    """absent_after_views 5: a chair of session 0 seen clearly (the wall behind it, one view: one
    counted non-detection, far from eq. 4's removal) in 3 frames of session 1 and 3 of session 2."""
    cfg = defaults()
    cfg["maintenance"]["absent_after_views"] = 5
    cfg["maintenance"]["absent_quiet_sessions"] = quiet
    cfg["maintenance"]["seen_empty_share"] = None
    smap = SemanticMap.new(CLASSES)
    t = smap.objects
    row = t.append(center=CHAIR_BOX[0], yaw=0.0, size=CHAIR_BOX[1], visible=np.ones(8, bool), defined=True,
                   scores=chair_vector(), n_det=50, status=ACTIVE, first_session=0, last_session=0)
    empty, _ = render([], wall_x=4.0)
    seen, masks = render([CHAIR_FACE], wall_x=4.0)
    for session in (1, 2):
        mapper = Mapper(smap, cfg, plugins.get("metrics", "vertex").factory(cfg["association"]),
                        plugins.get("policies", "non-detection").factory(cfg["maintenance"]), session=session)
        for k in range(3):
            if session == 2 and detect_in_session_2 and k == 0:
                mapper.process_frame(k, str(k), [masks[0]], [chair_vector(0.8)], seen, T_world_camera(), INTR,
                                     (0.3, 6.0))
            else:
                mapper.process_frame(k, str(k), [], [], empty, T_world_camera(), INTR, (0.3, 6.0))
        mapper.prune_unconfirmed(2, -1, "end", None)
        if session == 1:
            assert (t.status[row], t.clear_since_det[row]) == (ACTIVE, 3)
    assert t.status[row] == expected
    assert t.clear_since_det[row] == (2 if detect_in_session_2 else 6)


@pytest.mark.parametrize("mode, clear_for_absence, nondets", [
    ("absence", 1, 0),   # the absence rule's clear view only: no eq. 4 non-detection, n_clear 0
    (True, 1, 1),        # every count: a clear view and a (first, counted) non-detection
    (False, 0, 0),       # the paper: the table's box hides the cup
])
def test_a_cup_inside_a_table_box_counts_for_the_absence_rule_only(mode, clear_for_absence, nondets):
    """A cup of session 0 inside a loose table box of session 0, camera 2 m away, the cup taken away
    (depth: the wall at 4 m); neither is detected in this frame of session 1."""
    cfg = defaults()
    cfg["maintenance"]["hidden_by_whole_box"] = mode
    smap = SemanticMap.new(CLASSES)
    t = smap.objects
    b = boxes(CUP, TABLE)
    table = np.roll(chair_vector(), 1)  # class1 0.9 (a "table"): another class, 0.5 % of its volume: no merge
    table[-1], table[0] = 0.0, table[-1]
    rows = [t.append(center=b.center[i], yaw=0.0, size=b.size[i], visible=np.ones(8, bool), defined=True,
                     scores=s, n_det=20, status=ACTIVE, first_session=0, last_session=0)
            for i, s in ((0, chair_vector()), (1, table))]
    one_empty_frame(smap, cfg, rows)
    cup = rows[0]
    assert t.clear_in_session[cup] == clear_for_absence and t.clear_since_det[cup] == clear_for_absence
    assert t.n_nondet[cup] == nondets and t.n_clear[cup] == nondets


def test_absent_in_session_by_hand():
    """Session 3, absent_after_views 7. Objects: 0 seen 7 times in this session, undetected (gone);
    1 seen 6 times (stays); 2 last detected in session 1, 5 clear views since (gone with two quiet
    sessions and 5 quiet views, not with 7); 3 last detected in session 2 (one quiet session: stays);
    4 detected in this session (stays); 5 removed already; 6 created in this session (not judged)."""
    active = np.array([1, 1, 1, 1, 1, 0, 1], bool)
    first = np.array([0, 0, 0, 0, 0, 0, 3])
    last = np.array([2, 2, 1, 2, 3, 0, 3])
    clear_session = np.array([4, 4, 4, 4, 4, 4, 4])
    in_session = np.array([7, 6, 3, 6, 9, 9, 9])
    since = np.array([7, 6, 5, 6, 0, 9, 9])
    gone = absent_in_session(active, first, last, clear_session, in_session, 3, 7)
    assert gone.tolist() == [True, False, False, False, False, False, False]
    gone = absent_in_session(active, first, last, clear_session, in_session, 3, 7, since, 2, 5)
    assert gone.tolist() == [True, False, True, False, False, False, False]
    gone = absent_in_session(active, first, last, clear_session, in_session, 3, 7, since, 2, None)
    assert gone.tolist() == [True, False, False, False, False, False, False]


def test_stale_weight_by_hand():
    assert stale_weight(5.0, True, 1.0) == 1.0
    assert stale_weight(5.0, False, 1.0) == 5.0
    assert stale_weight(5.0, True, None) == 5.0
    assert stale_weight(0.5, True, 1.0) == 0.5


@pytest.mark.parametrize("cap, last_session, expected_y", [
    (1.0, 0, 0.15),        # first detection in session 1 of a session-0 chair: (0 + 0.3) / 2
    (None, 0, 0.05),       # no cap: the capped weight 5, (5 * 0 + 0.3) / 6
    (1.0, 1, 0.05),        # already detected in session 1: the weight 5 as before
])
def test_a_stale_box_weighs_at_most_the_cap_against_its_next_detection(cap, last_session, expected_y):
    """A Defined chair box at y 0 (20 detections: weight 5 under a cap of 5) and a Defined detection at y 0.3."""
    cfg = defaults()
    cfg["integration"]["max_weight"] = 5
    cfg["integration"]["stale_box_weight"] = cap
    smap = SemanticMap.new(CLASSES)
    t = smap.objects
    row = t.append(center=[2.2, 0.0, 0.6], yaw=0.0, size=[0.4, 0.6, 0.8], visible=np.ones(8, bool), defined=True,
                   scores=chair_vector(), n_det=20, status=ACTIVE, first_session=0, last_session=last_session)
    mapper = Mapper(smap, cfg, plugins.get("metrics", "vertex").factory(cfg["association"]),
                    plugins.get("policies", "non-detection").factory(cfg["maintenance"]), session=1)
    det = Box(np.array([2.2, 0.3, 0.6]), 0.0, np.array([0.4, 0.6, 0.8]), np.ones(8, bool), True)
    mapper._integrate(row, det, chair_vector(0.8), 0, "0")
    assert t.center[row][1] == pytest.approx(expected_y, abs=1e-9)
    assert t.last_session[row] == 1

"""maintenance.absent_through_views and nondet_through_share (issue 9, eighth round): the absence
rule removes an object, and a clear miss counts for eq. 4, only when the depth saw through its box,
not on the detector's silence alone. Expected values are
worked out by hand from the rendered scenes (tests/scene.py: camera at the origin looking along +x,
f 500, depth = x)."""

import numpy as np
import pytest

from ltc_cli import plugins
from ltc_cli.config import defaults
from ltc_cli.map.model import ACTIVE, REMOVED, SemanticMap
from ltc_cli.pipeline.maintenance import absent_in_session, count_absence_views, hole_shares, own_holes
from ltc_cli.pipeline.mapper import Mapper
from ltc_cli.pipeline.visibility import pixel_counts
from tests.scene import INTR, T_world_camera, render
from tests.test_identity import CHAIR_BOX, CHAIR_FACE, CLASSES, chair_vector
from tests.test_lap_rules import CUP, boxes


@pytest.mark.parametrize("scene, through_share, empty_share", [
    ([CUP], 0.0, (0.0, 0.0)),                             # the cup is there: rays stop at its face (2.0 m)
    ([], 1.0, (1.0, 1.0)),                                # taken away: rays reach the wall at 4 m
    ([(2.2, 2.3, -0.3, 0.3, 0.5, 1.5)], 1.0, (0.0, 0.2)),  # taken away from a shelf at its far side
])
def test_rays_past_the_middle_of_the_box(scene, through_share, empty_share):
    """The cup's box spans x 2.0-2.2: its middle along the central rays is at 2.1 m, and with a 3 cm
    margin a ray sees through it when the depth is beyond 2.13 m. Beyond the far side (the empty
    count of eq. 4's seen-empty rule) needs 2.2 + 0.2 m tolerance = 2.4 m: the shelf behind the
    cup's place (2.2 m) is seen through by the first; by the second only along the rays that graze
    the box's edges (they leave it near 2.0 m), 100 of the 676 sampled (15 %)."""
    depth, _ = render(scene, wall_x=4.0)
    vis, proj, empty, through = pixel_counts(boxes(CUP), T_world_camera(), depth, INTR, 2, 0.2, (0.3, 6.0),
                                             with_empty=True, past_middle=0.03)
    assert proj[0] == pytest.approx(2500, rel=0.1) and vis[0] == proj[0]
    assert through[0] == pytest.approx(through_share * vis[0])
    assert empty_share[0] * vis[0] <= empty[0] <= empty_share[1] * vis[0]


def test_absent_in_session_needs_views_that_saw_through():
    """Session 2, absent_after_views 3: all four objects of session 0 were seen clearly 4 times in
    this session and never detected; their places were seen through 0, 1, 2 and 4 times. Without
    the gate all go; with 2 views needed, the last two."""
    n = 4
    args = (np.ones(n, bool), np.zeros(n, int), np.zeros(n, int), np.full(n, 3), np.full(n, 4), 2, 3)
    through = np.array([0, 1, 2, 4])
    assert absent_in_session(*args).tolist() == [True] * 4
    gone = absent_in_session(*args, np.full(n, 4), None, None, through, 2)
    assert gone.tolist() == [False, False, True, True]
    # Two quiet sessions (none detected since session 0, 4 clear views since >= 3) stay enough.
    gone = absent_in_session(*args, np.full(n, 4), 2, None, through, 2)
    assert gone.tolist() == [True] * 4


def test_count_absence_views_by_hand():
    """Three objects in view in session 1; the first two clearly; the first detected; the second
    seen through. The counts start over in a new session (clear_session holds session + 1)."""
    cols = {"clear_session": np.array([2, 1, 2]), "clear_in_session": np.array([5, 7, 1]),
            "clear_since_det": np.array([0, 7, 1]), "through_since_det": np.array([0, 3, 1])}
    count_absence_views(cols, np.array([0, 1, 2]), np.array([True, True, False]), np.array([True, False, False]),
                        np.array([True, True, False]), 1)
    assert cols["clear_session"].tolist() == [2, 2, 2]          # object 1: its first clear view of session 1
    assert cols["clear_in_session"].tolist() == [6, 1, 1]
    assert cols["clear_since_det"].tolist() == [0, 8, 1]        # a detected object's count stays
    assert cols["through_since_det"].tolist() == [0, 4, 1]


def old_chair_in_session_1(cfg, **columns):
    """(object table, row, mapper): a chair of session 0 detected 50 times (with more ``columns``
    of the object table), and a mapper of session 1 over the map."""
    smap = SemanticMap.new(CLASSES)
    t = smap.objects
    row = t.append(center=CHAIR_BOX[0], yaw=0.0, size=CHAIR_BOX[1], visible=np.ones(8, bool), defined=True,
                   scores=chair_vector(), n_det=50, status=ACTIVE, first_session=0, last_session=0, **columns)
    mapper = Mapper(smap, cfg, plugins.get("metrics", "vertex").factory(cfg["association"]),
                    plugins.get("policies", "non-detection").factory(cfg["maintenance"]), session=1)
    return t, row, mapper


def lap_without_detections(depth, empty_views):
    """A chair of session 0, never detected in 6 frames of session 1 from one place (one counted
    eq. 4 miss: far from removal), then the session's end (absent_after_views 5)."""
    cfg = defaults()
    cfg["maintenance"]["absent_after_views"] = 5
    cfg["maintenance"]["absent_through_views"] = empty_views
    t, row, mapper = old_chair_in_session_1(cfg)
    for k in range(6):
        mapper.process_frame(k, str(k), [], [], depth, T_world_camera(), INTR, (0.3, 6.0))
    mapper.prune_unconfirmed(2, -1, "end", None)
    removed = [e.detail for e in mapper.map.events if e.kind == "removed"]
    return t.status[row], t.through_since_det[row], removed[-1] if removed else None


@pytest.mark.parametrize("chair_there, empty_views, expected, seen_through", [
    (True, None, REMOVED, 0),   # the detector's silence alone removes a chair still standing there
    (True, 2, ACTIVE, 0),       # the depth shows its face (2.0 m, the box's near side): it stays
    (False, 2, REMOVED, 6),     # taken away: the wall at 4 m in all 6 views
    (False, 7, ACTIVE, 6),      # ... but 6 views are fewer than 7
])
def test_a_chair_missed_for_a_whole_session_goes_only_when_its_place_was_seen_empty(chair_there, empty_views,
                                                                                     expected, seen_through):
    depth, _ = render([CHAIR_FACE] if chair_there else [], wall_x=4.0)
    status, through, reason = lap_without_detections(depth, empty_views)
    assert status == expected
    assert through == (seen_through if empty_views is not None else 0)
    if expected == REMOVED:  # the event log says what the camera saw
        assert reason == ("other: clearly visible in 6 frames of this session (6 since its last detection"
                          + (f", its place seen empty in {seen_through}" if empty_views is not None else "")
                          + "), detected in none")


def test_a_detection_starts_the_count_again():
    """through_since_det counts the views since the object's last detection, like clear_since_det."""
    t, row, mapper = old_chair_in_session_1(defaults())
    gone, _ = render([], wall_x=4.0)
    seen, masks = render([CHAIR_FACE], wall_x=4.0)
    for k in range(3):
        mapper.process_frame(k, str(k), [], [], gone, T_world_camera(), INTR, (0.3, 6.0))
    assert t.through_since_det[row] == 3
    mapper.process_frame(3, "3", [masks[0]], [chair_vector(0.8)], seen, T_world_camera(), INTR, (0.3, 6.0))
    assert t.through_since_det[row] == 0


@pytest.mark.parametrize("chair_there, share, nondets", [
    (True, 0.5, 0),      # the depth shows the chair's face: the detector's miss does not count
    (True, None, 1),     # the paper: every clear miss counts
    (False, 0.5, 1),     # taken away (the wall at 4 m): it counts
])
def test_a_miss_counts_only_where_the_depth_does_not_show_the_object(chair_there, share, nondets):
    cfg = defaults()
    cfg["maintenance"]["nondet_through_share"] = share
    cfg["maintenance"]["spare_frames"] = None
    t, row, mapper = old_chair_in_session_1(cfg)
    depth, _ = render([CHAIR_FACE] if chair_there else [], wall_x=4.0)
    mapper.process_frame(0, "0", [], [], depth, T_world_camera(), INTR, (0.3, 6.0))
    assert t.n_nondet[row] == nondets
    assert t.n_clear[row] == 1  # clearly visible either way


# A screen at 1 m hides the left 60 % of the chair's place: in angle the place spans y/x from
# -0.15 to 0.15 (0.3 m at 2 m), the screen -1.0 to 0.03 (y -1 to 0.03 m at 1 m), so 0.18 of 0.30.
SCREEN = (1.0, 1.05, -1.0, 0.03, 0.0, 2.0)


@pytest.mark.parametrize("share, expected, clear", [
    (0.0, REMOVED, 6),   # the visible 40 % all show the wall behind the chair's place: it went
    (0.5, ACTIVE, 0),    # as every other view: 40 % visible is under half, no clear view
])
def test_a_place_seen_empty_in_part_is_a_clear_view_for_the_absence_rule(share, expected, clear):
    """maintenance.through_visible_share: the chair of session 0 was taken away; in 6 frames the
    camera sees 40 % of its place, all of it through to the wall at 4 m. With the default 0 the
    depth's word needs no half of the object in view, and the absence rule (5 views) removes it;
    with min_visible_share's 0.5 none of the views is clear. Eq. 4 counts no miss either way (40 %
    is under min_visible_share), so the removal is the absence rule's."""
    depth, _ = render([SCREEN], wall_x=4.0)
    cfg = defaults()
    cfg["maintenance"]["absent_after_views"] = 5
    cfg["maintenance"]["through_visible_share"] = share
    t, row, mapper = old_chair_in_session_1(cfg)
    for k in range(6):
        mapper.process_frame(k, str(k), [], [], depth, T_world_camera(), INTR, (0.3, 6.0))
    assert t.clear_since_det[row] == clear and t.n_nondet[row] == 0
    mapper.prune_unconfirmed(2, -1, "end", None)
    assert t.status[row] == expected


# A dark screen in the chair's place: no depth reading left of column 305 (y > 0.06 m at 2 m), the
# wall at 4 m to the right. The chair's box images as columns 245-394 (y 0.3 to -0.3 at 2 m):
# 60 of its 150 columns have no reading, 90 see the wall.
def dark_left_depth():
    depth, _ = render([], wall_x=4.0)
    depth[:, :305] = 0.0
    return depth


def test_unread_pixels_of_a_box_by_hand():
    vis, proj, empty, through, unread = pixel_counts(boxes(CHAIR_FACE), T_world_camera(), dark_left_depth(), INTR, 1,
                                                     0.2, (0.3, 6.0), with_empty=True, past_middle=0.03, unread=True)
    assert vis[0] == pytest.approx(0.6 * proj[0]) and unread[0] == pytest.approx(0.4 * proj[0])
    assert through[0] == vis[0]  # every reading is the wall, past the middle (2.2 m) by more than 3 cm


@pytest.mark.parametrize("holes, dark, nondets", [
    (True, True, 0),    # 61 % visible (a clear view), all of it the wall: 0.61 of visible + unread < 0.65
    (False, True, 1),   # over the visible pixels alone, 100 % seen through: the miss counts
    (True, False, 1),   # no screen: the wall everywhere, the miss counts either way
])
def test_a_miss_where_the_depth_has_no_reading_does_not_count(holes, dark, nondets):
    """maintenance.nondet_through_holes (twenty-fifth round): at ray_step 8 the box samples 28800
    pixels, 17600 with the wall's reading and 11200 without (the same 60 / 150 columns)."""
    cfg = defaults()
    cfg["maintenance"]["spare_frames"] = None
    cfg["maintenance"]["nondet_through_holes"] = holes
    t, row, mapper = old_chair_in_session_1(cfg)
    depth = dark_left_depth() if dark else render([], wall_x=4.0)[0]
    mapper.process_frame(0, "0", [], [], depth, T_world_camera(), INTR, (0.3, 6.0))
    assert t.n_nondet[row] == nondets
    assert t.n_clear[row] == 1  # clearly visible either way (17600 >= half of 28800)


def test_hole_shares_and_own_holes_by_hand():
    np.testing.assert_allclose(hole_shares([60, 0, 0], [40, 0, 10]), [0.4, 0.0, 1.0])
    # Means 20 / 50 = 0.4, 2 / 10 = 0.2, none yet.
    assert list(own_holes([20.0, 2.0, 0.0], [50, 10, 0], 0.3)) == [True, False, False]
    assert list(own_holes([20.0, 2.0, 0.0], [50, 10, 0], 0.2)) == [True, True, False]
    assert not own_holes([20.0, 2.0, 0.0], [50, 10, 0], None).any()


@pytest.mark.parametrize("baseline, share, expected, seen_through", [
    (0.0, 0.3, REMOVED, 6),   # its detected views had depth all over its box: the wall is its place seen empty
    (0.4, 0.3, ACTIVE, 0),    # 40 % of its box had no depth when detected (a dark screen): the holes are its
                              # own, and 17600 / 28800 = 0.61 seen through is under absent_through_share 0.75
    (0.2, 0.3, REMOVED, 6),   # 20 % is under the 0.3 of the setting
    (0.4, None, REMOVED, 6),  # the setting off
])
def test_holes_that_are_the_things_own_are_no_view_of_its_place(baseline, share, expected, seen_through):
    """maintenance.absent_holes_share (forty-third round): two simulated televisions, dark screens
    without depth, went as absent because the wall around the screen inside the box was all the
    depth showed. Here the chair's box in dark_left_depth, in 6 frames: at stage 4's ray_step 8,
    17600 of its 28800 pixels read the wall at 4 m (past its middle) and 11200 have no reading."""
    cfg = defaults()
    cfg["maintenance"]["absent_after_views"] = 5
    cfg["maintenance"]["absent_through_views"] = 2
    cfg["maintenance"]["absent_holes_share"] = share
    t, row, mapper = old_chair_in_session_1(cfg, n_clear_det=50, det_holes=50 * baseline)
    for k in range(6):
        mapper.process_frame(k, str(k), [], [], dark_left_depth(), T_world_camera(), INTR, (0.3, 6.0))
    mapper.prune_unconfirmed(2, -1, "end", None)
    assert t.status[row] == expected
    assert t.through_since_det[row] == seen_through
    assert t.n_nondet[row] == 0  # eq. 4 counts the holes already (nondet_through_holes): no miss either way


def test_a_detected_view_adds_its_share_of_holes():
    """The chair detected in a frame whose depth has no reading left of column 305: at stage 4's
    ray_step 8 its box samples 28800 pixels, 11200 without a reading (as in
    test_a_miss_where_the_depth_has_no_reading_does_not_count), so det_holes grows by 11200 / 28800."""
    t, row, mapper = old_chair_in_session_1(defaults())
    depth, masks = render([CHAIR_FACE], wall_x=4.0)
    depth[:, :305] = 0.0
    res = mapper.process_frame(0, "0", masks, [chair_vector()], depth, T_world_camera(), INTR, (0.3, 6.0))
    assert (res.matched, res.created) == (1, 0)
    assert t.n_clear_det[row] == 1
    assert t.det_holes[row] == pytest.approx(11200 / 28800)

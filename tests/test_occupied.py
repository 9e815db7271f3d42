"""maintenance.occupied_margin (issue 9, twenty-third round): a small thing whose box lies beside it
(the localiser's drift) is not "seen through" while the depth shows it within the margin of its
box. Expected values are worked out by hand from the rendered scenes (tests/scene.py: camera looking
along +x from height 1 m, depth = x)."""

import numpy as np
import pytest

from ltc_cli import plugins
from ltc_cli.config import defaults
from ltc_cli.geometry.boxes import Boxes
from ltc_cli.map.model import ACTIVE, REMOVED, SemanticMap
from ltc_cli.pipeline.maintenance import stands_there
from ltc_cli.pipeline.mapper import Mapper
from ltc_cli.pipeline.visibility import occupied_pixels
from ltc_cli.types import Intrinsics
from tests.scene import INTR, T_world_camera, render

# 20 x 20 pixels, f 10: at 2 m a pixel is 0.2 m, and pixel u, v sees y = -(u - 9.5) / 5,
# z = 1 - (v - 9.5) / 5. A patch u, v = 8..11 at 2 m: y in {0.3, 0.1, -0.1, -0.3},
# z in {1.3, 1.1, 0.9, 0.7}; a wall at 3 m elsewhere.
TINY = Intrinsics(20, 20, 10.0, 10.0, 9.5, 9.5)


def patch_depth(hole=None, at=2.0):
    depth = np.full((20, 20), 3.0)
    depth[8:12, 8:12] = at
    if hole is not None:
        depth[hole] = 0.0
    return depth


def one_box(center, size, yaw=0.0):
    return Boxes(np.array([center], float), np.array([yaw]), np.array([size], float), np.ones((1, 8), bool))


@pytest.mark.parametrize("margin, lift, yaw, size, hole, expected", [
    # grown y 0.07..0.43 holds columns y 0.3, 0.1; z 0.85..1.38 the rows 1.3, 1.1, 0.9: 2 x 3
    (0.08, 0.15, 0.0, (0.2, 0.2, 0.6), None, 6),
    (0.08, 0.15, 0.0, (0.2, 0.2, 0.6), (8, 8), 5),       # no reading at (u 8, v 8): not a point
    # y 0.13..0.37: the column y 0.3 only; z 0.75..1.32: 1.3, 1.1, 0.9
    (0.02, 0.05, 0.0, (0.2, 0.2, 0.6), None, 3),
    # the same box turned a quarter: 0.5 m along y (0.0..0.5, grown -0.02..0.52): y 0.3 and 0.1
    (0.02, 0.05, np.pi / 2, (0.5, 0.2, 0.6), None, 6),
    (0.02, 0.05, 0.0, (0.5, 0.2, 0.6), None, 3),
])
def test_occupied_pixels_by_hand(margin, lift, yaw, size, hole, expected):
    """The box stands at x 2.0, y 0.25, z 0.7..1.3; the wall's points (x = 3) are never inside."""
    occ = occupied_pixels(one_box((2.0, 0.25, 1.0), size, yaw), T_world_camera(), patch_depth(hole), TINY, 1,
                          margin, lift)
    assert occ.tolist() == [expected]


@pytest.mark.parametrize("at, past_middle, expected", [
    (2.08, None, 6),    # the patch 8 cm past the box's middle (x 2.0), still inside the grown box
    (2.08, 0.03, 0),    # ... is where rays through the box end (a wall it touches), not the thing
    (2.02, 0.03, 6),    # within 3 cm of the middle: the thing
])
def test_depth_past_the_middle_is_not_the_thing(at, past_middle, expected):
    """The patch at x = at is 4 x 4 pixels of 0.2 * at / 2 m each; the columns at y 0.3 * at / 2
    and 0.1 * at / 2 (0.31, 0.10 at 2.08 m) lie in y 0.07..0.43, the rows at z 1 +- 0.3 * at / 2 and
    1 +- 0.1 * at / 2 (1.31, 1.10, 0.90, 0.69) the three upper in z 0.85..1.38: 6 as before."""
    occ = occupied_pixels(one_box((2.0, 0.25, 1.0), (0.2, 0.2, 0.6)), T_world_camera(), patch_depth(at=at), TINY,
                          1, 0.08, 0.15, past_middle)
    assert occ.tolist() == [expected]


def test_stands_there_by_hand():
    occupied = np.array([0.0, 50.0, 200.0, 300.0])
    visible = np.array([0.0, 1000.0, 1000.0, 1000.0])
    assert stands_there(occupied, visible, 0.2).tolist() == [False, False, True, True]
    assert stands_there(occupied, visible, 0.25).tolist() == [False, False, False, True]


# A cup 0.1 wide and 0.12 tall with its face at 1.5 m (1 px = 3 mm: 33 x 40 px); its box, from an
# earlier session, lies 0.09 m to its left (y 0.04..0.14): one of its 10 cm is the cup, so 90 % of
# the box's rays pass the cup and end on the wall at 4 m. Grown by 8 cm (y -0.04..0.22) and raised
# by 3 cm at the bottom (z 0.93..1.10), the box holds the cup's face over y -0.04..0.05, z
# 0.93..1.02: 9 x 9 cm, about 900 of the box's 1333 visible pixels (0.68 >= 0.15); the face (1.5
# m) is not past the box's middle (1.55 m).
CUP_FACE = (1.5, 1.6, -0.05, 0.05, 0.9, 1.02)
CUP_BOX = [1.55, 0.09, 0.96], [0.1, 0.1, 0.12]


def old_cup_in_session_1(margin):
    cfg = defaults()
    cfg["maintenance"]["occupied_margin"] = margin
    smap = SemanticMap.new(["chair", "cup"])
    t = smap.objects
    row = t.append(center=CUP_BOX[0], yaw=0.0, size=CUP_BOX[1], visible=np.ones(8, bool), defined=True,
                   scores=np.array([0.05, 0.95, 0.0]), n_det=30, status=ACTIVE, first_session=0, last_session=0)
    mapper = Mapper(smap, cfg, plugins.get("metrics", "vertex").factory(cfg["association"]),
                    plugins.get("policies", "non-detection").factory(cfg["maintenance"]), session=1)
    return t, row, mapper


def test_the_grown_cup_box_holds_the_cup_by_hand():
    depth, _ = render([CUP_FACE], wall_x=4.0)
    occ = occupied_pixels(one_box(*CUP_BOX), T_world_camera(), depth, INTR, 2, 0.08, 0.03, 0.03)
    assert occ[0] == pytest.approx(30 * 30, rel=0.1)


@pytest.mark.parametrize("cup_there, margin, expected, nondets, through", [
    (True, 0.08, ACTIVE, 0, 0),     # the default: the cup stands 9 cm from its box's middle
    (True, None, REMOVED, 6, 6),    # the rule off: the rays that pass it say "seen through", it goes
    (False, 0.08, REMOVED, 6, 6),   # taken away: nothing within 8 cm, the wall at 4 m
])
def test_a_small_thing_beside_its_box_is_not_seen_through(cup_there, margin, expected, nondets, through):
    """Six frames of session 1 from one place, the cup never detected, then the session's end
    (absent_after_views 4, absent_through_views 2). 90 % of the box's rays end on the wall, 2.4 m
    past its far side: a miss seen empty (seen_empty_share 0.75) counts in every frame."""
    depth, _ = render([CUP_FACE] if cup_there else [], wall_x=4.0)
    t, row, mapper = old_cup_in_session_1(margin)
    for k in range(6):
        mapper.process_frame(k, str(k), [], [], depth, T_world_camera(), INTR, (0.3, 6.0))
    assert t.n_clear[row] == 6
    assert t.n_nondet[row] == nondets and t.through_since_det[row] == through
    mapper.prune_unconfirmed(2, -1, "end", None)
    assert t.status[row] == expected

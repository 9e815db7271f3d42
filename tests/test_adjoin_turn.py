"""association.adjoin_max_turn (issue 9, thirty-fourth round): a partial view adjoins a piece of its
class only when their long footprint axes lie along one line. On tum-fr1-rpy read every fourth
frame, the front monitor's screen (0.6 x 0.1 m) adjoined the second monitor's partial box, turned
18 degrees against it, and the two were one 1.05 m "tv" over the white mouse. Values by hand."""

import numpy as np
import pytest

from ltc_cli.config import defaults
from ltc_cli.pipeline.association import long_axis_turns
from tests.adjoin_check import mapper_with_piece, view_beside_piece

TV = np.array([1.0, 0.0, 0.0])  # over ["tv", "chair"] and other
SCREEN = (2.0, 2.02, -0.6, 0.0, 0.9, 1.2)  # its face 2 m ahead, y -0.6 .. 0, z 0.9 .. 1.2


def test_long_axis_turns_by_hand():
    screen = np.array([0.6, 0.1, 0.3])  # long along its yaw
    # The second monitor 0.41 x 0.25 turned 18 degrees; the same with its sides named the other way
    # round (yaw 90 degrees on, x and y swapped); a square box has no long axis.
    yaws = np.radians([18.0, 108.0, 18.0, 170.0])
    sizes = np.array([[0.41, 0.25, 0.3], [0.25, 0.41, 0.3], [0.3, 0.3, 0.3], [0.5, 0.1, 0.3]])
    out = np.degrees(long_axis_turns(0.0, screen, yaws, sizes, 1.5))
    np.testing.assert_allclose(out, [18.0, 18.0, 0.0, 10.0], atol=1e-9)  # 170 degrees is 10 off a line
    # 0.41 / 0.25 = 1.64: elongated at 1.5, not at 2.
    assert long_axis_turns(0.0, screen, yaws[:1], sizes[:1], 2.0)[0] == 0.0


def piece_mapper(turn_deg, limits):
    """A map holding a partial "tv" 0.41 x 0.1 x 0.3 m whose near end lies 3 cm past the screen's
    end (y 0.03), its long axis turned ``turn_deg`` from the screen's (along y)."""
    cfg = defaults()
    cfg["association"]["adjoin_max_turn"] = limits
    a = np.radians(90.0 + turn_deg)
    axis = np.array([np.cos(a), np.sin(a)])
    center = np.r_[np.array([2.05, 0.03]) + 0.205 * axis, 1.05]
    return mapper_with_piece(cfg, ["tv", "chair"], center, a - np.pi, [0.41, 0.1, 0.3], TV)


@pytest.mark.parametrize("turn, limits, joins", [
    (18.0, {"tv": 10.0}, False),  # the default: two monitors side by side
    (0.0, {"tv": 10.0}, True),  # one screen seen in two pieces
    (18.0, {}, True),  # any turn (the rule off)
    (18.0, {"chair": 10.0}, True),  # the rule for another class
])
def test_a_screen_adjoins_a_piece_along_its_line_only(turn, limits, joins):
    """The screen's footprint ends at y 0 (plus thinning's width back), the piece's 3 cm on; joined,
    the piece's box takes the screen."""
    view_beside_piece(piece_mapper(turn, limits), SCREEN, TV, joins, reach_y=-0.55)

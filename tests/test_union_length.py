"""association.max_union_length (issue 9, thirty-fifth round): two things of a class that is never
that long are not one box. Expected values by hand."""

import numpy as np
import pytest

from ltc_cli import plugins
from ltc_cli.config import defaults
from ltc_cli.geometry.boxes import Boxes
from ltc_cli.pipeline.association import longer_sides, too_long_together, union_diameters
from ltc_cli.pipeline.deduplication import merge_pairs


def boxes(*rows):
    """Boxes from (x, sx, sy) rows: centre (x, 0, 0.78), yaw 0, 0.06 m tall, partial."""
    return Boxes(np.array([[x, 0.0, 0.78] for x, _, _ in rows]), np.zeros(len(rows)),
                 np.array([[sx, sy, 0.06] for _, sx, sy in rows]), np.zeros((len(rows), 8), bool))


def feet(b: Boxes) -> np.ndarray:
    return b.corners[:, :4, :2]


# A trackball (0.12 x 0.08 m at x 0), the controller beside it (0.156 x 0.088 m at x 0.145, 0.7 cm
# apart) and a monitor's foot called "mouse" (0.27 x 0.14 m at x 0.2).
TRACKBALL, CONTROLLER, FOOT = (0.0, 0.12, 0.08), (0.145, 0.156, 0.088), (0.2, 0.27, 0.14)


def test_union_diameters_by_hand():
    """Unit squares at x 0 and x 2: from (-0.5, -0.5) to (2.5, 0.5), sqrt(9 + 1); one box with
    itself: its diagonal. Trackball and controller: from (-0.06, -0.04) to (0.223, 0.044), sqrt(0.283^2
    + 0.084^2) = 0.2952."""
    two = boxes((0, 1, 1), (2, 1, 1))
    assert union_diameters(feet(two)[:1], feet(two)[1:]) == pytest.approx([np.sqrt(10)])
    assert union_diameters(feet(two)[:1], feet(two)[:1]) == pytest.approx([np.sqrt(2)])
    pair = boxes(TRACKBALL, CONTROLLER)
    assert union_diameters(feet(pair)[:1], feet(pair)[1:]) == pytest.approx([0.2952], abs=1e-4)


def test_too_long_together_by_hand():
    """At 0.25 m: the trackball with the controller (0.295 together, 0.144 and 0.179 alone) is too
    long; with a second view of itself 2 cm over (0.14 x 0.08 together: 0.161) it is not; the foot,
    0.304 alone, is no mouse, and the rule says nothing of it; no limit (inf), nothing."""
    b = boxes(TRACKBALL, CONTROLLER, (0.02, 0.12, 0.08), FOOT)
    f = feet(b)
    a_side, b_side = f[[0, 0, 0, 0]], f[[1, 2, 3, 1]]
    assert too_long_together(a_side, b_side, np.array([0.25, 0.25, 0.25, np.inf])).tolist() == \
        [True, False, False, False]
    assert too_long_together(a_side, b_side, np.inf).tolist() == [False] * 4


def test_a_wide_box_within_the_limit_is_judged_by_hand():
    """A partial "mouse" grown to 0.2 x 0.2 m: longer side 0.2, within 0.25, diagonal sqrt(0.08) =
    0.283 beyond it. A trackball-sized box at x 0.15 reaches past it (together from (-0.1, 0.1) to
    (0.21, -0.04): sqrt(0.31^2 + 0.14^2) = 0.340 > 0.283): too long. One inside it (at x 0.02, up
    to 0.08) adds no span (0.283, its own): not. The foot's longer side, 0.27, is beyond the limit:
    not judged. Until the thirty-ninth round the wide box, 0.283 corner to corner, was not judged."""
    b = boxes((0.0, 0.2, 0.2), (0.15, 0.12, 0.08), (0.02, 0.12, 0.08), FOOT)
    f = feet(b)
    assert longer_sides(f) == pytest.approx([0.2, 0.12, 0.12, 0.27])
    assert union_diameters(f[[0, 0]], f[[1, 2]]) == pytest.approx([np.hypot(0.31, 0.14), np.sqrt(0.08)])
    assert too_long_together(f[[0, 0, 0]], f[[1, 2, 3]], 0.25).tolist() == [True, False, False]
    assert too_long_together(f[[1, 2]], f[[0, 0]], 0.25).tolist() == [True, False]  # either order


@pytest.mark.parametrize("limit, merged", [(None, True), (0.25, False), (0.3, True)])
def test_two_mice_side_by_side_do_not_merge(limit, merged):
    """The trackball's partial box and the controller's at x 0.11, overlapping by 0.028 x 0.08 m
    (23 % of the trackball's footprint, over merge_min_overlap's 20 %), are a pair to merge: not
    with a 0.25 m limit for their class (together from (-0.06, -0.04) to (0.188, 0.044): sqrt(0.248^2
    + 0.084^2) = 0.262 m), again with 0.3."""
    cfg = defaults()
    b = boxes(TRACKBALL, (0.11, 0.156, 0.088))
    assert union_diameters(feet(b)[:1], feet(b)[1:]) == pytest.approx([0.2618], abs=1e-4)
    top = np.array([0, 0])
    max_union = None if limit is None else np.array([limit, np.inf])
    metric = plugins.get("metrics", "vertex").factory(cfg["association"])
    pairs = merge_pairs(b, top, metric.distance, cfg["association"], defined=np.zeros(2, bool),
                        first_session=np.zeros(2, int), session=0, max_union=max_union)
    assert [(a, c) for _, a, c in pairs] == ([(0, 1)] if merged else [])

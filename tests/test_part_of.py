"""integration.defined_part_volume (issue 9, twenty-first round): a Defined box far smaller than a
partial object's box and lying inside it is a view of a part of the object (the back of a chair),
and does not replace the partial box, which says the object is at least that large. Values worked
out by hand from the tum-fr1-rpy boxes of the four-session run."""

import numpy as np
import pytest

from ltc_cli.geometry.boxes import Box
from ltc_cli.pipeline.integration import integrate_box, merge_objects, part_of

# The chair: partial, x -1.89..-0.85, y -0.625..0.325, z 0.015..1.125; volume 1.04 x 0.95 x 1.11
# = 1.09668 m^3. Its back: Defined, x -1.685..-1.135, y -0.35..-0.17, z 0.555..1.045, wholly
# inside; 0.55 x 0.18 x 0.49 = 0.04851 m^3, 4.42 % of the chair's. The chair's vertices 0, 1, 4, 5
# were seen (its x and z edges), so it is partial.
CHAIR = Box(np.array([-1.37, -0.15, 0.57]), 0.0, np.array([1.04, 0.95, 1.11]), np.isin(np.arange(8), [0, 1, 4, 5]),
            False)
BACK = Box(np.array([-1.41, -0.26, 0.80]), 0.0, np.array([0.55, 0.18, 0.49]), np.ones(8, bool), True)


def moved(box: Box, dx: float) -> Box:
    return Box(box.center + [dx, 0.0, 0.0], box.yaw, box.size.copy(), box.visible.copy(), box.defined)


@pytest.mark.parametrize("det, share, expected", [
    (BACK, 0.1, True),              # 4.42 % of the volume, all of it inside
    (BACK, 0.04, False),            # over 4 %: not small enough
    (BACK, None, False),            # the paper
    # 0.45 m towards -x: x -2.135..-1.585, of which -1.89..-1.585 (0.305 of 0.55 m, 55 %) inside
    (moved(BACK, -0.45), 0.1, False),
    # 0.05 m towards -x: x -1.735..-1.185, 0.505 of 0.55 m (91.8 %) inside: still a part
    (moved(BACK, -0.05), 0.1, True),
])
def test_part_of_by_hand(det, share, expected):
    assert part_of(det, CHAIR, share) is expected


def test_a_part_does_not_replace_the_partial_box():
    """The paper's rule replaces the chair's box by its back's; with the rule the two enclose: the
    chair's box, eroded by 0.01 m per side where the back does not reach it, stays partial."""
    replaced = integrate_box(BACK, CHAIR, 1.0, 5.0, 0.01, 0.05)
    np.testing.assert_allclose(replaced.size, BACK.size)
    assert replaced.defined
    kept = integrate_box(BACK, CHAIR, 1.0, 5.0, 0.01, 0.05, part_volume=0.1)
    assert not kept.defined
    assert np.all(kept.size >= CHAIR.size - 0.02 - 1e-9) and np.all(kept.size <= CHAIR.size + 1e-9)
    assert np.abs(kept.center - CHAIR.center).max() <= 0.01 + 1e-9
    # A merge of the two map objects (the chair older, the back newer) keeps the chair's box too.
    box, scores = merge_objects(CHAIR, BACK, np.array([0.98, 0.02]), np.array([0.46, 0.54]), 5.0, 5.0, 0.01, 0.05,
                                part_volume=0.1)
    assert not box.defined and np.all(box.size >= CHAIR.size - 0.02 - 1e-9)
    np.testing.assert_allclose(scores, [0.72, 0.28])  # eq. 3 generalised: the weighted mean


def test_labelled_part_pairs_by_hand():
    """association.part_label_share: the chair's back (BACK, 4.42 % of CHAIR's volume, all inside)
    whose class vector says tv 0.52 / chair 0.38 is the chair under another label: a pair with
    0.35, keyed 1 - 0.38 = 0.62. With chair 0.34, or volume share 0.04, or the rule off, none. A cup
    inside the chair's box (a cup on a table) with nothing of the chair in its evidence: none."""
    from ltc_cli.geometry.boxes import Boxes
    from ltc_cli.pipeline.deduplication import labelled_part_pairs

    TV, CHAIR_CLASS, CUP = 0, 1, 2
    cup = Box(np.array([-1.2, 0.1, 0.6]), 0.0, np.array([0.1, 0.1, 0.12]), np.ones(8, bool), True)
    b = Boxes(np.stack([CHAIR.center, BACK.center, cup.center]), np.zeros(3), np.stack([CHAIR.size, BACK.size, cup.size]),
              np.ones((3, 8), bool))
    top = np.array([CHAIR_CLASS, TV, CUP])
    scores = np.array([[0.02, 0.96, 0.0, 0.02], [0.52, 0.38, 0.0, 0.10], [0.0, 0.0, 0.9, 0.1]])
    pairs = labelled_part_pairs(b, top, scores, 0.35, 0.1)
    assert [(a, c) for _, a, c in pairs] == [(0, 1)]
    assert pairs[0][0] == pytest.approx(0.62)
    weaker = scores.copy()
    weaker[1, CHAIR_CLASS] = 0.34
    assert labelled_part_pairs(b, top, weaker, 0.35, 0.1) == []
    assert labelled_part_pairs(b, top, scores, 0.35, 0.04) == []
    assert labelled_part_pairs(b, top, scores, None, 0.1) == []

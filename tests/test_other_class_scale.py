"""The other-class threshold of eq. 2 scaled by the boxes' size (association.other_class_scale,
issue 9 seventh round): one object under two labels gives boxes apart by less than its size, two
small objects of different classes side by side do not. Values worked out by hand."""

import numpy as np
import pytest

from ltc_cli.geometry.boxes import Boxes
from ltc_cli.pipeline.association import size_caps, thresholds_for
from ltc_cli.pipeline.deduplication import duplicate_pairs


def test_caps_by_hand():
    # Half diagonals: a 0.1 x 0.1 x 0.1 cup 0.0866, a 0.2 x 0.1 x 0.1 "mouse" 0.1225, a 1.6 x 0.9 x
    # 0.75 table 0.9631; the cap is scale times the larger of the pair.
    det = np.array([0.2, 0.1, 0.1])
    cands = np.array([[0.1, 0.1, 0.1], [1.6, 0.9, 0.75]])
    caps = size_caps(det, cands, 1.25)
    np.testing.assert_allclose(caps, [1.25 * np.sqrt(0.06) / 2, 1.25 * np.sqrt(1.6**2 + 0.81 + 0.5625) / 2])
    assert size_caps(det, cands, None) is None
    # Same class keeps its 0.4; other class is min(0.25, cap): 0.153 for the cup, 0.25 for the table.
    thr = thresholds_for(0, np.array([1, 1, 0]), 0.4, 0.25, np.array([caps[0], caps[1], 0.01]))
    np.testing.assert_allclose(thr, [1.25 * np.sqrt(0.06) / 2, 0.25, 0.4])


def boxes(centers, sizes):
    c = np.asarray(centers, float)
    return Boxes(c, np.zeros(len(c)), np.asarray(sizes, float), np.ones((len(c), 8), bool))


def centre_distance(one: Boxes, many: Boxes) -> np.ndarray:
    return np.linalg.norm(many.center - one.center[0], axis=1)


@pytest.mark.parametrize("scale, merged", [(None, True), (1.25, False)])
def test_a_mug_and_a_foot_side_by_side_stay_two_objects(scale, merged):
    """A 0.1 m mug and a 0.2 x 0.1 x 0.1 "mouse" 0.2 m apart (tum-fr1-rpy's mug and monitor foot),
    of different classes: within the fixed 0.25 m they merge; the cap 1.25 x 0.1225 = 0.153 m keeps
    them apart. The metric here is the centre distance, so the figures stay hand-checkable."""
    b = boxes([[0.0, 0.0, 0.05], [0.2, 0.0, 0.05]], [[0.1, 0.1, 0.1], [0.2, 0.1, 0.1]])
    pairs = duplicate_pairs(b, np.array([0, 1]), centre_distance, 0.4, 0.25, None, None, other_scale=scale)
    assert (pairs == [(pytest.approx(0.2), 0, 1)]) if merged else (pairs == [])


def test_one_table_under_two_labels_still_merges():
    """A 1.6 m table seen as "table" and as "book" 0.2 m apart: the cap (1.25 x 0.963 = 1.2 m) does
    not bind, the fixed 0.25 m decides, and they merge as before."""
    b = boxes([[0.0, 0.0, 0.4], [0.2, 0.0, 0.4]], [[1.6, 0.9, 0.75], [1.5, 0.9, 0.75]])
    pairs = duplicate_pairs(b, np.array([0, 1]), centre_distance, 0.4, 0.25, None, None, other_scale=1.25)
    assert pairs == [(pytest.approx(0.2), 0, 1)]

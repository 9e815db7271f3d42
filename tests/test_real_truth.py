"""The checks tests/real_truth.py holds real maps to, on boxes placed by hand (no ../shared needed)."""

from types import SimpleNamespace

import numpy as np

from ltc_cli.map.model import ACTIVE, REMOVED
from tests.real_truth import Landmark, merged_pairs

A = Landmark("mouse A", "mouse", 0, (0, 0), (0.0, 0.0, 0.05))
B = Landmark("mouse B", "mouse", 0, (0, 0), (0.2, 0.0, 0.05))


def a_map(rows):
    """rows: (top class index, status, centre, size) with yaw 0; classes tv, mouse (and other)."""
    scores = np.zeros((len(rows), 3))
    scores[np.arange(len(rows)), [r[0] for r in rows]] = 1.0
    objects = SimpleNamespace(status=np.array([r[1] for r in rows]), scores=scores,
                              center=np.array([r[2] for r in rows], float), yaw=np.zeros(len(rows)),
                              size=np.array([r[3] for r in rows], float))
    return SimpleNamespace(objects=objects, classes=["tv", "mouse"], up_rotation=np.eye(3))


def test_one_box_of_the_class_over_both_places_is_reported_with_its_id():
    """Mouse 1 spans x -0.05..0.25 and holds both places; mouse 2 spans -0.05..0.05, 0.15 m short of
    B (more than NEAR 0.05); mouse 3 spans 0.17..0.27, holds B and is 0.17 m from A; the tv over both
    is another class; mouse 5 over both was removed. Only mouse 1 holds both."""
    smap = a_map([(1, ACTIVE, (0.1, 0.0, 0.05), (0.3, 0.1, 0.1)),
                  (1, ACTIVE, (0.0, 0.0, 0.05), (0.1, 0.1, 0.1)),
                  (1, ACTIVE, (0.22, 0.0, 0.05), (0.1, 0.1, 0.1)),
                  (0, ACTIVE, (0.1, 0.0, 0.2), (1.0, 1.0, 0.5)),
                  (1, REMOVED, (0.1, 0.0, 0.05), (0.3, 0.1, 0.1))])
    assert merged_pairs(smap, [("mouse A", "mouse B")], landmarks=(A, B)) == [("mouse A", "mouse B", 1)]


def test_a_box_within_near_of_both_places_counts_and_one_further_does_not():
    """A 0.1 m box centred at x 0.1 ends 0.05 m from each place (NEAR: counts); a 0.3 m one over
    both in x but centred 0.11 m off their line, its side 0.06 m from both, does not."""
    near = a_map([(1, ACTIVE, (0.1, 0.0, 0.05), (0.1, 0.1, 0.1))])
    far = a_map([(1, ACTIVE, (0.1, 0.11, 0.05), (0.3, 0.1, 0.1))])
    assert merged_pairs(near, [("mouse A", "mouse B")], landmarks=(A, B)) == [("mouse A", "mouse B", 1)]
    assert merged_pairs(far, [("mouse A", "mouse B")], landmarks=(A, B)) == []

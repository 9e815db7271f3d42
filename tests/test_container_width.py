"""association.container_max_width (issue 9, 25th and 26th rounds): a map object of a class whose
footprint's longer side is over the class's bound is no single object of it, and never merges with
a partial object of another class by containment, inside or around it; a Defined one still joins.
Values worked out by hand."""

import numpy as np
import pytest

from ltc_cli import plugins
from ltc_cli.config import load_config
from ltc_cli.geometry.boxes import Boxes
from ltc_cli.pipeline.association import too_wide
from ltc_cli.pipeline.deduplication import merge_pairs

CLASSES = ["chair", "dining table"]  # then other
BOUND = np.array([1.2, np.inf, np.inf])  # {chair: 1.2}, as the classes' vector (other last)


def test_too_wide_by_hand():
    top = np.array([0, 0, 0, 1])
    size = np.array([[1.85, 1.60, 1.3],   # a chair blob: 1.85 > 1.2
                     [0.50, 1.21, 0.9],   # the longer side is the y one: 1.21 > 1.2
                     [1.20, 0.60, 0.9],   # exactly at the bound: one chair
                     [3.00, 1.00, 0.7]])  # a table has no bound
    assert too_wide(top, size, BOUND).tolist() == [True, True, False, False]
    assert too_wide(top, size, None).tolist() == [False] * 4


def two_boxes(chair_size, table_defined):
    """A partial "chair" box on the floor (footprint centred on the origin) and a 0.77 x 0.88 x 0.82
    dining table whose box lies wholly inside it (its footprint [-0.285, 0.485] x [-0.64, 0.24])."""
    center = np.array([[0.0, 0.0, chair_size[2] / 2], [0.1, -0.2, 0.41]])
    size = np.array([chair_size, [0.77, 0.88, 0.82]])
    boxes = Boxes(center, np.zeros(2), size, np.ones((2, 8), bool))
    return boxes, np.array([False, table_defined])


@pytest.mark.parametrize("chair_size, table_defined, overrides, merge", [
    # The table is 100 % inside the 1.85 x 1.6 x 1.34 blob (>= containment_other_class 0.7), of
    # 0.556 / 3.966 = 0.14 of its volume (>= other_class_volume_ratio 0.1), but the blob is too wide.
    ([1.85, 1.60, 1.34], False, [], False),
    ([1.85, 1.60, 1.34], False, ["association.container_max_width=null"], True),
    ([1.85, 1.60, 1.34], False, ["association.container_max_width={}"], True),
    ([1.85, 1.60, 1.34], True, [], True),    # a Defined table still joins (its box replaces the blob's)
    # A 1.15 x 1.10 x 1.34 chair (an armchair): 1.15 <= 1.2, the table (0.33 of its volume) joins.
    ([1.15, 1.10, 1.34], False, [], True),
])
def test_a_too_wide_object_takes_in_no_partial_object_of_another_class(chair_size, table_defined, overrides, merge):
    cfg = load_config(None, overrides)
    a_cfg = cfg["association"]
    boxes, defined = two_boxes(chair_size, table_defined)
    metric = plugins.get("metrics", "vertex").factory(a_cfg)
    widths = a_cfg["container_max_width"] or {}
    bound = np.array([float(widths.get(c, np.inf)) for c in CLASSES] + [np.inf])
    pairs = merge_pairs(boxes, np.array([0, 1]), metric.distance, a_cfg, None, defined, np.zeros(2, int), 0, None,
                        None, None, bound)
    assert {(a, b) for _, a, b in pairs} == ({(0, 1)} if merge else set())
    if merge:
        # By containment first (eq. 2 is far over the 0.25 m threshold); the armchair's footprint
        # also overlaps the table's by XY IoU 0.678 / 1.265 = 0.54, a pair of two labels after it.
        assert pairs[0][0] < 1e6


@pytest.mark.parametrize("chair_width, overrides, merge", [
    # A Defined 1.45 x 0.53 x 0.94 "chair" (two chairs) at (0, 0.5): footprint x [-0.725, 0.725],
    # y [0.235, 0.765], inside the partial 1.83 x 1.97 x 0.86 table's [-0.915, 0.915] x [-0.985,
    # 0.985]; 0.86 / 0.94 = 0.915 of it inside (>= 0.7), of 0.7224 / 3.1004 = 0.233 of its volume
    # (>= 0.1). Too wide: it does not go into the partial table.
    (1.45, [], False),
    (1.45, ["association.container_max_width=null"], True),
    # One chair 1.0 m wide (0.498 / 3.1004 = 0.16 of the table's volume) is no blob: the rule
    # leaves it to containment as before.
    (1.0, [], True),
])
def test_a_too_wide_object_goes_into_no_partial_object_of_another_class(chair_width, overrides, merge):
    cfg = load_config(None, overrides)
    a_cfg = cfg["association"]
    boxes = Boxes(np.array([[0.0, 0.5, 0.47], [0.0, 0.0, 0.43]]), np.zeros(2),
                  np.array([[chair_width, 0.53, 0.94], [1.83, 1.97, 0.86]]), np.ones((2, 8), bool))
    metric = plugins.get("metrics", "vertex").factory(a_cfg)
    widths = a_cfg["container_max_width"] or {}
    bound = np.array([float(widths.get(c, np.inf)) for c in CLASSES] + [np.inf])
    pairs = merge_pairs(boxes, np.array([0, 1]), metric.distance, a_cfg, None, np.array([True, False]),
                        np.zeros(2, int), 0, None, None, None, bound)
    assert {(a, b) for _, a, b in pairs} == ({(0, 1)} if merge else set())
    if merge:
        assert pairs[0][0] < 1e6  # by containment (eq. 2 is far over the other-class threshold)

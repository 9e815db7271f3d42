"""A later partial view of a Defined object merges into it (association merge_partial_defined_gap /
_volume, issue 9: a revisit of tum-fr1-rpy made a 1.4 m partial chair beside a 0.5 m chair)."""

import numpy as np
import pytest

from ltc_cli import plugins
from ltc_cli.config import defaults
from ltc_cli.geometry.boxes import Boxes
from ltc_cli.pipeline.deduplication import merge_pairs, partial_defined_pairs

CHAIR, TABLE = 0, 3

# Footprints (x range, y range) and z ranges, all axis-aligned, worked out by hand:
# 0 Defined chair   x -0.25..0.25  y -0.25..0.25  z 0..0.9
# 1 partial chair   x  0.20..1.60  y -0.20..0.20  z 0..0.9   overlaps 0 by 0.05 x 0.4: gap 0; 0.08 of 0's
#                   volume inside 1, 0.036 of 1's inside 0 (under merge_containment 0.3); centres 0.9 apart
# 2 partial chair   x  2.30..3.70  y -0.20..0.20  z 0..0.9   2.05 from 0
# 3 partial table   x -1.45..-0.25 y -0.20..0.20  z 0..0.9   touches 0, another class
# 4 partial chair   x -0.25..0.25  y  0.20..1.00  z 1.3..1.7 footprint on 0's, z apart
# 5 Defined chair   x -0.25..0.25  y -0.75..-0.25 z 0..0.9   touches 0 (two Defined: eq. 2's business);
#                   0.05 from 1 in y
# 6 partial chair   x -0.25..0.25  y  0.30..0.70  z 0..0.9   0.05 from 0 in y
# Volumes: 0 and 5 0.225; 1 and 2 0.504 (2.24 x 0.225); 3 0.432; 4 0.16; 6 0.18 (0.8 x 0.225).
# Objects 0 and 5 were first detected in session 0, the others in session 1, except 6 (session 0).
CENTER = [[0, 0, 0.45], [0.9, 0, 0.45], [3.0, 0, 0.45], [-0.85, 0, 0.45], [0, 0.6, 1.5], [0, -0.5, 0.45],
          [0, 0.5, 0.45]]
SIZE = [[0.5, 0.5, 0.9], [1.4, 0.4, 0.9], [1.4, 0.4, 0.9], [1.2, 0.4, 0.9], [0.5, 0.8, 0.4], [0.5, 0.5, 0.9],
        [0.5, 0.4, 0.9]]
TOP = np.array([CHAIR, CHAIR, CHAIR, TABLE, CHAIR, CHAIR, CHAIR])
DEFINED = np.array([True, False, False, False, False, True, False])
FIRST = np.array([0, 1, 1, 1, 1, 0, 0])


def scene() -> Boxes:
    return Boxes(np.array(CENTER, float), np.zeros(7), np.array(SIZE, float), np.ones((7, 8), bool))


def test_partial_defined_pairs_by_hand():
    boxes = scene()
    pairs = partial_defined_pairs(boxes, TOP, DEFINED, FIRST, 0.0, 2.0)
    assert [(a, b) for _, a, b in pairs] == [(0, 1)]
    assert pairs[0][0] == pytest.approx(0.0)
    assert partial_defined_pairs(boxes, TOP, DEFINED, FIRST, None, 2.0) == []
    # A gap of 0.1 m adds 1 with 5 (0.05 m); 6 is as old as 0 and smaller, so never.
    wider = partial_defined_pairs(boxes, TOP, DEFINED, FIRST, 0.1, 2.0)
    assert sorted((a, b) for _, a, b in wider) == [(0, 1), (1, 5)]
    assert sorted(g for g, _, _ in wider) == pytest.approx([0.0, 0.05])
    # 6 from a later session: still under twice 0's volume (0.8); with no volume test it pairs.
    later = np.array([0, 1, 1, 1, 1, 0, 1])
    assert sorted((a, b) for _, a, b in partial_defined_pairs(boxes, TOP, DEFINED, later, 0.1, 2.0)) == [(0, 1), (1, 5)]
    assert sorted((a, b) for _, a, b in partial_defined_pairs(boxes, TOP, DEFINED, later, 0.1, 0.0)) == \
        [(0, 1), (0, 6), (1, 5)]
    # 1 first seen in the session of 0 and 5: no pair at any gap.
    same = np.array([0, 0, 1, 1, 1, 0, 0])
    assert partial_defined_pairs(boxes, TOP, DEFINED, same, 0.1, 2.0) == []
    # A volume ratio over 1's (2.24): no pair either.
    assert partial_defined_pairs(boxes, TOP, DEFINED, FIRST, 0.1, 2.3) == []


@pytest.mark.parametrize("gap", [None, 0.0])
def test_merge_pairs_joins_the_partial_chair_only_with_the_setting(gap):
    a_cfg = defaults()["association"]
    a_cfg["merge_partial_defined_gap"] = gap
    metric = plugins.get("metrics", "vertex").factory(a_cfg)
    pairs = {(a, b) for _, a, b in merge_pairs(scene(), TOP, metric.distance, a_cfg, None, DEFINED, FIRST)}
    # Without the rule nothing pairs 0 and 1: eq. 2 sees 0.9 m between centres, containment 0.08.
    assert ((0, 1) in pairs) == (gap is not None)
    assert (0, 5) not in pairs and (0, 3) not in pairs and (0, 4) not in pairs

"""Two partial pieces of one long object already in the map merge (association.merge_adjoining,
issue 9 twenty-third round: held-out house 201 kept three boxes for one dining table)."""

import numpy as np

from ltc_cli import plugins
from ltc_cli.config import defaults, load_config
from ltc_cli.geometry.boxes import Boxes
from ltc_cli.pipeline.deduplication import adjoining_part_pairs, merge_pairs

TABLE, CHAIR = 0, 1
SHARE = np.array([0.1, 0.0, 0.0])  # dining table 0.1, chair none, other none

# Footprints (x range; all y -0.3..0.3) and z ranges, axis-aligned, worked out by hand:
# 0 partial table  x -0.50..0.50  z 0..0.8   longer side 1.0: a gap of max(0.05, 0.1 x 1.0) = 0.1 joins
# 1 partial table  x  0.58..1.18  z 0..0.8   0.08 from 0
# 2 partial table  x  1.30..1.90  z 0..0.8   0.12 from 1 (longer side 0.6 x 0.1 = 0.06 < 0.12), 0.8 from 0
# 3 partial chair  x -1.08..-0.58 z 0..0.8   0.08 from 0, another class
# 4 Defined table  x -0.50..0.50  z 1.0..1.8 above 0, z apart
# Footprint areas: 0 and 4 0.6 m2, 1 and 2 0.36 m2, 3 0.3 m2.
CENTER = [[0, 0, 0.4], [0.88, 0, 0.4], [1.6, 0, 0.4], [-0.83, 0, 0.4], [0, 0, 1.4]]
SIZE = [[1.0, 0.6, 0.8], [0.6, 0.6, 0.8], [0.6, 0.6, 0.8], [0.5, 0.6, 0.8], [1.0, 0.6, 0.8]]
TOP = np.array([TABLE, TABLE, TABLE, CHAIR, TABLE])


def scene(n=5) -> Boxes:
    return Boxes(np.array(CENTER[:n], float), np.zeros(n), np.array(SIZE[:n], float), np.ones((n, 8), bool))


def test_adjoining_part_pairs_by_hand():
    defined = np.array([False, False, False, False, True])
    pairs = adjoining_part_pairs(scene(), TOP, defined, SHARE, 0.05)
    assert [(a, b) for _, a, b in pairs] == [(0, 1)]
    assert abs(pairs[0][0] - 0.08) < 1e-9
    # A share of 0.25 of the 0.6 m sides reaches 0.15: 1 and 2 (0.12 apart) join; 0 and 2 (0.8
    # apart, 0.25 of 1.0 m) do not.
    assert [(a, b) for _, a, b in adjoining_part_pairs(scene(), TOP, defined, SHARE * 2.5, 0.05)] == [(0, 1), (1, 2)]
    # A Defined piece takes in a partial one no larger (0: 0.6 m2, 1: 0.36 m2), not a larger one;
    # two Defined pieces are two things.
    defined[1] = True
    assert adjoining_part_pairs(scene(), TOP, defined, SHARE, 0.05) == []
    defined[:2] = [True, False]
    assert [(a, b) for _, a, b in adjoining_part_pairs(scene(), TOP, defined, SHARE, 0.05)] == [(0, 1)]
    defined[:2] = [True, True]
    assert adjoining_part_pairs(scene(), TOP, defined, SHARE, 0.05) == []
    assert adjoining_part_pairs(scene(), TOP, np.zeros(5, bool), None, 0.05) == []


def test_merge_pairs_takes_adjoining_pieces_by_the_settings():
    """With the defaults the pieces 0 and 1 are a merge pair (after every other rule's pairs);
    with docs/paper.yaml (merge_adjoining false, no containment) they are not."""
    boxes, defined, first = scene(2), np.zeros(2, bool), np.zeros(2, int)
    for cfg, expected in ((defaults(), [(0, 1)]), (load_config("docs/paper.yaml", []), [])):
        a_cfg = cfg["association"]
        metric = plugins.get("metrics", "vertex").factory(a_cfg)
        share = SHARE if a_cfg["merge_adjoining"] else None
        pairs = merge_pairs(boxes, TOP[:2], metric.distance, a_cfg, None, defined, first, 0, None, None, share)
        assert [(a, b) for _, a, b in pairs] == expected

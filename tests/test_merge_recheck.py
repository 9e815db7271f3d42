"""A frame's merges are found again on the merged boxes (association merge_recheck, issue 9,
forty-third round): simulated house 505 had a partial "dining table" blob over a chair; a Defined
view of the table replaced the blob, and then the chair, paired with the blob before that merge,
swallowed the table."""

import numpy as np
import pytest

from ltc_cli.config import defaults
from ltc_cli.map.model import ACTIVE, MERGED
from ltc_cli.pipeline.deduplication import greedy_merges
from tests.mappers import mapper_with_boxes, merge_seen_from_origin

CLASSES = ["chair", "dining table"]

# Seen from the origin along +x; boxes axis-aligned, worked out by hand:
# 0 chair, Defined       x 2.25..2.75  y  0.25..0.75  z 0..0.9   volume 0.225
# 1 table blob, partial  x 1.75..3.25  y -0.75..0.75  z 0..0.9   volume 2.025: holds all of 0
#                        (0.225 / 2.025 = 0.11 of its volume, over other_class_volume_ratio 0.1)
# 2 table, Defined       x 1.90..3.10  y -0.45..0.25  z 0..0.8   inside 1; touches 0 along y = 0.25
# Pairs on these boxes: (1, 2) one class, 2 inside 1; (0, 1) 0 inside 1, and 1's vector gives chair
# 0.2 (over merge_other_class_evidence 0.1). (1, 2) is the closer: 1 keeps its id and the Defined
# box of 2 replaces the blob. On that box, 0 and 1 only touch: no containment, and eq. 2 over their
# vertices is far over the other-class threshold.
CENTER = [[2.5, 0.5, 0.45], [2.5, 0.0, 0.45], [2.5, -0.1, 0.4]]
SIZE = [[0.5, 0.5, 0.9], [1.5, 1.5, 0.9], [1.2, 0.7, 0.8]]
DEFINED = [True, False, True]
SCORES = [[0.9, 0.0, 0.1], [0.2, 0.7, 0.1], [0.0, 0.9, 0.1]]
N_DET = [14, 14, 2]


def mapper_with_scene(recheck: bool):
    cfg = defaults()
    cfg["association"]["merge_recheck"] = recheck
    return mapper_with_boxes(CLASSES, cfg, CENTER, SIZE, DEFINED, SCORES, N_DET)


@pytest.mark.parametrize("recheck", [True, False])
def test_the_chair_keeps_out_of_the_table_once_its_box_is_the_table(recheck):
    mapper = mapper_with_scene(recheck)
    t = mapper.map.objects
    merged = merge_seen_from_origin(mapper)
    if not recheck:
        # The old way: both pairs found on the first boxes, both applied; the chair and the table
        # end as one object.
        assert merged == 2
        assert (t.status == ACTIVE).sum() == 1
        return
    assert merged == 1
    assert list(t.status) == [ACTIVE, ACTIVE, MERGED]
    # The chair untouched; the table object (id 2) holds the Defined table box.
    np.testing.assert_allclose(t.center[0], CENTER[0])
    np.testing.assert_allclose(t.size[0], SIZE[0])
    np.testing.assert_allclose(t.center[1], CENTER[2])
    np.testing.assert_allclose(t.size[1], SIZE[2])
    assert t.n_det[1] == 16


def test_greedy_merges_disjoint_puts_each_object_in_one_merge():
    # Pairs by key: (0, 1) then (1, 2) then (2, 3); ids 1..4 (the older keeps its id).
    pairs = [(0.1, 0, 1), (0.2, 1, 2), (0.3, 2, 3)]
    ids = np.array([1, 2, 3, 4])
    # Once: 1 is dropped, so (1, 2) goes; 2 keeps 3.
    assert greedy_merges(pairs, ids) == [(0, 1), (2, 3)]
    assert greedy_merges(pairs, ids, disjoint=True) == [(0, 1), (2, 3)]
    # A kept object: (0, 1) keeps 0, and (0, 2) would merge 0 again on its old box.
    pairs = [(0.1, 0, 1), (0.2, 0, 2), (0.3, 2, 3)]
    assert greedy_merges(pairs, ids) == [(0, 1), (0, 2)]
    assert greedy_merges(pairs, ids, disjoint=True) == [(0, 1), (2, 3)]

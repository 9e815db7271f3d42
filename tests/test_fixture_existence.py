"""maintenance.fixture_existence: eq. 4 removes a built-in thing only when `other` outweighs all
its classes together (issue 9, twenty-sixth round). Values worked out by hand."""

import numpy as np

from ltc_cli.config import defaults
from ltc_cli.map.model import ACTIVE, REMOVED
from ltc_cli.pipeline.maintenance import other_leads, other_outweighs
from tests.scene import INTR, T_world_camera, render
from tests.test_accuracy_rules import every_miss_counts, mapper_with_chair
from tests.test_identity import CLASSES


def test_other_outweighs_by_hand():
    scores = np.array([[0.30, 0.25, 0.05, 0.40],    # other leads (0.40) but 0.40 < 0.60
                       [0.20, 0.20, 0.05, 0.55],    # 0.55 > 0.45
                       [0.25, 0.25, 0.00, 0.50]])   # 0.50 = 0.50: not over
    assert other_leads(scores).tolist() == [True, True, True]
    assert other_outweighs(scores).tolist() == [False, True, False]


def split_chair():
    """chair 0.4, class1 0.3 (a label the detector also gives it), 0.3 / 8 on each other class."""
    s = np.full(len(CLASSES) + 1, 0.3 / 8)
    s[0], s[1], s[-1] = 0.4, 0.3, 0.0
    return s


def misses_until_removed(fixture: bool, existence: bool, frames: int = 10):
    """Eq. 4 with v_Other 0.8 (0.02 on each of the 10 classes) and D = 5: after k misses each entry
    is v + (s0 - v) a with a = (5/6)^k: other 0.8 (1 - a), chair 0.02 + 0.38 a, the classes
    together 0.2 + 0.8 a. `other` leads chair from a < 0.78 / 1.18 = 0.661 (k = 3: a = 0.579, other
    0.337 > chair 0.240); it outweighs all classes from a < 0.6 / 1.6 = 0.375 (k = 6: a = 0.335,
    other 0.532 > 0.468; at k = 5, a = 0.402: 0.479 < 0.521)."""
    cfg = every_miss_counts(defaults())
    cfg["maintenance"]["v_other"] = 0.8
    cfg["maintenance"]["fixture_classes"] = ["chair"] if fixture else []
    cfg["maintenance"]["fixture_existence"] = existence
    mapper, row = mapper_with_chair(cfg, n_det=30, scores=split_chair())
    empty, _ = render([], wall_x=4.0)
    for k in range(1, frames + 1):
        mapper.process_frame(k, str(k), [], [], empty, T_world_camera(), INTR, (0.3, 6.0))
        if mapper.map.objects.status[row] == REMOVED:
            return k
    assert mapper.map.objects.status[row] == ACTIVE
    return None


def test_a_fixture_with_split_labels_goes_when_other_outweighs_them_all():
    assert misses_until_removed(fixture=True, existence=True) == 6
    assert misses_until_removed(fixture=True, existence=False) == 3
    assert misses_until_removed(fixture=False, existence=True) == 3  # not a fixture: the policy's rule

"""association.adjoin_except (issue 9, forty-second round): chairs stand side by side, a few
centimetres apart, and a partial view of one touches the partial box of the next as a second piece
of one long thing does. Adjoined, they grow into one box over several chairs. Values by hand."""

import numpy as np
import pytest

from ltc_cli.config import defaults
from tests.adjoin_check import mapper_with_piece, view_beside_piece

CLASSES = ["chair", "dining table", "oven", "refrigerator"]
# A seat's front seen 2 m ahead: x 2.0 .. 2.02, y -0.45 .. 0, z 0.45 .. 0.9 (its back hidden).
FRONT = (2.0, 2.02, -0.45, 0.0, 0.45, 0.9)


@pytest.mark.parametrize("cls, adjoin_except, joins", [
    ("chair", ["chair"], False),  # the default: the next chair along the row
    ("chair", [], True),  # every class adjoins (before the forty-second round)
    ("dining table", ["chair"], True),  # a table seen in two pieces still joins
    # An oven beside the refrigerator whose first views called it "oven" (forty-third round):
    ("oven", ["chair", "oven", "refrigerator"], False),  # the default
    ("oven", ["chair"], True),  # the forty-second round's default: one "oven" over both
    ("refrigerator", ["chair", "oven", "refrigerator"], False),
])
def test_a_chair_view_does_not_adjoin_the_chair_beside_it(cls, adjoin_except, joins):
    """The map holds a partial ``cls`` box 0.45 x 0.45 x 0.45 m standing 3 cm beside the seen front
    (y 0.03 .. 0.48): the next chair along the row, made by earlier views."""
    cfg = defaults()
    assert cfg["association"]["adjoin_except"] == ["chair", "oven", "refrigerator"]
    cfg["association"]["adjoin_except"] = adjoin_except
    scores = np.eye(len(CLASSES) + 1)[CLASSES.index(cls)]
    mapper = mapper_with_piece(cfg, CLASSES, [2.225, 0.255, 0.675], 0.0, [0.45, 0.45, 0.45], scores)
    view_beside_piece(mapper, FRONT, scores, joins, reach_y=-0.4)
    if not joins:
        assert not mapper.map.objects.defined[1]

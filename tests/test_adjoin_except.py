"""association.adjoin_except (issue 9, forty-second round): chairs stand side by side, a few
centimetres apart, and a partial view of one touches the partial box of the next as a second piece
of one long thing does. Adjoined, they grow into one box over several chairs. Values by hand."""

import numpy as np
import pytest

from ltc_cli import plugins
from ltc_cli.config import defaults
from ltc_cli.geometry.boxes import Boxes
from ltc_cli.map.model import ACTIVE, SemanticMap
from ltc_cli.pipeline.association import footprint_gaps
from ltc_cli.pipeline.mapper import Mapper
from tests.scene import INTR, T_world_camera, render

CLASSES = ["chair", "dining table"]
# A seat's front seen 2 m ahead: x 2.0 .. 2.02, y -0.45 .. 0, z 0.45 .. 0.9 (its back hidden).
FRONT = (2.0, 2.02, -0.45, 0.0, 0.45, 0.9)


def mapper_with_piece(cls: str, adjoin_except: list):
    """A map holding a partial ``cls`` box 0.45 x 0.45 x 0.45 m standing 3 cm beside the seen front
    (y 0.03 .. 0.48): the next chair along the row, made by earlier views."""
    cfg = defaults()
    cfg["association"]["adjoin_except"] = adjoin_except
    smap = SemanticMap.new(CLASSES)
    mapper = Mapper(smap, cfg, plugins.get("metrics", "vertex").factory(cfg["association"]),
                    plugins.get("policies", "non-detection").factory(cfg["maintenance"]))
    scores = np.eye(len(CLASSES) + 1)[CLASSES.index(cls)]
    center, size = np.array([2.225, 0.255, 0.675]), np.array([0.45, 0.45, 0.45])
    row = smap.objects.append(center=center, yaw=0.0, size=size, visible=np.zeros(8, bool), defined=False,
                              scores=scores, n_det=5, n_nondet=0, status=ACTIVE)
    mapper.index.insert(row, center, size)
    return mapper, scores


@pytest.mark.parametrize("cls, adjoin_except, joins", [
    ("chair", ["chair"], False),  # the default: the next chair along the row
    ("chair", [], True),  # every class adjoins (before the forty-second round)
    ("dining table", ["chair"], True),  # a table seen in two pieces still joins
])
def test_a_chair_view_does_not_adjoin_the_chair_beside_it(cls, adjoin_except, joins):
    mapper, scores = mapper_with_piece(cls, adjoin_except)
    t = mapper.map.objects
    piece = t.boxes(np.array([0]))
    depth, masks = render([FRONT], wall_x=4.0)
    res = mapper.process_frame(1, "f1", masks, [scores], depth, T_world_camera(), INTR, (0.3, 6.0))
    if joins:
        assert (res.created, res.matched) == (0, 1)
        assert t.boxes(np.array([0])).corners[0][:, 1].min() < -0.4  # the piece's box took the view
        return
    assert (res.created, res.matched) == (1, 0)
    np.testing.assert_allclose(t.center[0], piece.center[0])
    np.testing.assert_allclose(t.size[0], piece.size[0])
    # The setting, not the gap, kept them apart: the new box lies within partial_adjoin_gap.
    gap = footprint_gaps(t.boxes(np.array([1])), Boxes(piece.center, piece.yaw, piece.size, piece.visible))[0]
    assert 0.0 <= gap <= mapper.cfg["association"]["partial_adjoin_gap"]
    assert not t.defined[1]

"""integration.stale_partial_moves (issue 9, eighth round): a partial detection whose footprint does
not touch the Defined box of the object it matched, last detected in an earlier session, moves the
box (the object was moved). Boxes and expected values are worked out by hand."""

import numpy as np
import pytest

from ltc_cli import plugins
from ltc_cli.config import defaults
from ltc_cli.geometry.boxes import Box
from ltc_cli.map.model import ACTIVE, SemanticMap
from ltc_cli.pipeline.integration import moved_elsewhere
from ltc_cli.pipeline.mapper import Mapper

CLASSES = ["bottle", "cup"]  # then other


def box(x, sx, defined):
    return Box(np.array([x, 0.0, 0.8]), 0.0, np.array([sx, 0.08, 0.28]), np.ones(8, bool), defined)


@pytest.mark.parametrize("det_x, det_defined, obj_defined, stale, expected", [
    (0.15, False, True, True, True),    # 0.11-0.19 against -0.035-0.035: 7.5 cm apart, stale: moved
    (0.15, False, True, False, False),  # the same in the object's own session: the paper's rule
    (0.06, False, True, True, False),   # 0.02-0.10 overlaps the box (0.015 m): a partial view of it
    (0.15, True, True, True, False),    # a Defined detection is averaged (stale_box_weight)
    (0.15, False, False, True, False),  # a partial object grows by the enclosing box as before
])
def test_moved_elsewhere_by_hand(det_x, det_defined, obj_defined, stale, expected):
    obj = box(0.0, 0.07, obj_defined)
    det = box(det_x, 0.08, det_defined)
    assert moved_elsewhere(det, obj, stale) is expected


def test_a_millimetre_decides():
    """The object's box spans x -0.035-0.035 and the detection's is 0.08 wide: centred at 0.0755 it
    spans 0.0355-0.1155, 0.5 mm clear of the box (moved); at 0.074, 0.034-0.114, 1 mm over it (a
    partial view of the object where it stands)."""
    obj = box(0.0, 0.07, True)
    assert moved_elsewhere(box(0.0755, 0.08, False), obj, True)
    assert not moved_elsewhere(box(0.074, 0.08, False), obj, True)


def mapper_with_bottle(cfg, session):
    smap = SemanticMap.new(CLASSES)
    row = smap.objects.append(center=np.array([0.0, 0.0, 0.8]), yaw=0.0, size=np.array([0.07, 0.08, 0.28]),
                              visible=np.ones(8, bool), defined=True, scores=np.array([0.9, 0.1, 0.0]), n_det=10,
                              status=ACTIVE, first_session=0, last_session=0)
    mapper = Mapper(smap, cfg, plugins.get("metrics", "vertex").factory(cfg["association"]),
                    plugins.get("policies", "non-detection").factory(cfg["maintenance"]), session=session)
    return mapper, row


@pytest.mark.parametrize("moves, session, expected_x", [
    (True, 1, 0.15),    # stale: the box goes where the bottle is now
    (True, 0, 0.0),     # detected in this session already: the Defined box stays
    (False, 1, 0.0),    # the paper (docs/paper.yaml): the Defined box stays
])
def test_the_mapper_moves_a_stale_box_to_a_partial_view_elsewhere(moves, session, expected_x):
    cfg = defaults()
    cfg["integration"]["stale_partial_moves"] = moves
    mapper, row = mapper_with_bottle(cfg, session)
    mapper._integrate(row, box(0.15, 0.08, False), np.array([0.8, 0.2, 0.0]), 0, "0")
    t = mapper.map.objects
    assert t.center[row, 0] == pytest.approx(expected_x)
    assert bool(t.defined[row]) is (expected_x == 0.0)  # a moved box is partial until seen whole
    assert t.n_det[row] == 11


def test_default_and_paper():
    import yaml
    from pathlib import Path

    assert defaults()["integration"]["stale_partial_moves"] is True
    paper = yaml.safe_load((Path(__file__).resolve().parent.parent / "docs" / "paper.yaml").read_text())
    assert paper["integration"]["stale_partial_moves"] is False

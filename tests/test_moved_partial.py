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
    ("seen-empty", 1, 0.0),  # ... only once stage 4 sees its old place empty (below)
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

    assert defaults()["integration"]["stale_partial_moves"] == "seen-empty"
    paper = yaml.safe_load((Path(__file__).resolve().parent.parent / "docs" / "paper.yaml").read_text())
    assert paper["integration"]["stale_partial_moves"] is False


# tests/scene.py: the camera at the origin looks along +x, depth = x. The bottle of session 0 stood
# at x 2.0-2.1, y -0.05-0.05, z 0.7-1.0 (its face 0.1 x 0.3 m at 2 m: 25 x 75 px); now one stands
# at y 0.10-0.20, 5 cm clear of the old footprint.
OLD_BOTTLE = (2.0, 2.1, -0.05, 0.05, 0.7, 1.0)
NEW_BOTTLE = (2.0, 2.1, 0.10, 0.20, 0.7, 1.0)


@pytest.mark.parametrize("old_still_there, seen_apart, expected_y", [
    (False, 0.03, 0.15), (True, None, 0.0), (True, 0.03, 0.0)])
def test_seen_empty_moves_only_when_the_old_place_is_empty(old_still_there, seen_apart, expected_y):
    """stale_partial_moves: seen-empty (issue 9, twenty-first round). The frame's one "bottle"
    mask is the new bottle's face: a partial box (its depth unmeasured) 15 cm from the old one, which
    it matches. With the old place empty the rays through the old box reach the wall at 4 m, past
    its middle (2.05 m): the box moves to the new bottle (its centre y 0.15, partial). With a bottle
    still standing there the rays stop at 2.0 m: the box stays (y 0, Defined). Without
    association.seen_apart_gap the detection still counts for it; with it (the default, thirty-third
    round) the depth shows the old bottle standing in its box 5 cm from the new one's, over the
    0.03 m gap: the new bottle is a second object, and the old one keeps its 10 detections."""
    from tests.scene import INTR, T_world_camera, render

    cfg = defaults()
    cfg["association"]["seen_apart_gap"] = seen_apart
    mapper, row = mapper_with_bottle(cfg, session=1)
    t = mapper.map.objects
    t.cols["center"][row] = [2.05, 0.0, 0.85]
    t.cols["size"][row] = [0.1, 0.1, 0.3]
    mapper.index.insert(row, t.center[row], t.size[row])
    scene = [NEW_BOTTLE, OLD_BOTTLE] if old_still_there else [NEW_BOTTLE]
    depth, masks = render(scene, wall_x=4.0)
    mapper.process_frame(0, "0", [masks[0]], [np.array([0.9, 0.1, 0.0])], depth, T_world_camera(), INTR, (0.3, 6.0))
    two = old_still_there and seen_apart is not None
    assert t.n_det[row] == (10 if two else 11) and t.status[row] == ACTIVE and t.n == (2 if two else 1)
    assert t.center[row, 1] == pytest.approx(expected_y, abs=0.02)
    assert bool(t.defined[row]) is old_still_there
    if two:
        assert t.center[1, 1] == pytest.approx(0.15, abs=0.02) and t.status[1] == ACTIVE

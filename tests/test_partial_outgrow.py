"""integration.partial_outgrow (issue 9, seventeenth round): a partial box of the object's own class
reaching further than the margin outside a Defined box proves the Defined box too small; the box
grows along its own axes to cover it and stays Defined. Boxes and expected values are worked out by hand."""

import numpy as np
import pytest
import yaml
from pathlib import Path

from ltc_cli import plugins
from ltc_cli.config import defaults
from ltc_cli.geometry.boxes import Box, box_corners
from ltc_cli.map.model import ACTIVE, SemanticMap
from ltc_cli.pipeline.integration import (
    integrate_box, merge_objects, reach_beyond, shares_inside, square_turn, takes_in,
)
from ltc_cli.pipeline.mapper import Mapper

CLASSES = ["couch", "bed", "chair"]  # then other


def box(x0, x1, defined, y0=-0.45, y1=0.45, yaw=0.0):
    """An axis-aligned box (yaw 0) spanning x0-x1, y0-y1 and z 0-0.8."""
    return Box(np.array([(x0 + x1) / 2, (y0 + y1) / 2, 0.4]), yaw, np.array([x1 - x0, y1 - y0, 0.8]),
               np.ones(8, bool), defined)


def extent(b: Box):
    c = box_corners(b.center, b.yaw, b.size)
    return np.round(np.concatenate([c.min(axis=0), c.max(axis=0)]), 6)


def test_reach_beyond_by_hand():
    whole = box(-0.35, 0.35, True)
    assert reach_beyond(box(-0.3, 0.3, False, -0.2, 0.2), whole) == 0.0         # inside
    assert reach_beyond(box(-1.2, 0.3, False), whole) == pytest.approx(0.85)    # -1.2 against -0.35
    assert reach_beyond(box(0.0, 0.5, False, -0.6, 0.2), whole) == pytest.approx(0.15)  # x 0.15, y 0.15
    # The whole box turned 90 degrees: its 0.7 m side now lies along y (x -0.45-0.45, y -0.35-0.35);
    # a partial box over y 0.1-0.6 reaches 0.25 m beyond it, and along x nothing.
    turned = Box(np.array([0.0, 0.0, 0.4]), np.pi / 2, np.array([0.7, 0.9, 0.8]), np.ones(8, bool), True)
    assert reach_beyond(box(-0.4, 0.4, False, 0.1, 0.6), turned) == pytest.approx(0.25)


def test_a_partial_view_reaching_beyond_grows_the_defined_box():
    """A 0.7 m Defined piece of a couch (x -0.35-0.35) and a partial view over x -1.2-0.3: the box
    grows along its own axes to x -1.19 (the partial side, less 0.01 of erosion) and keeps its own
    side at 0.35; y and z, where the partial box reaches no further, stay as they were."""
    whole, partial = box(-0.35, 0.35, True), box(-1.2, 0.3, False)
    new = integrate_box(partial, whole, 1, 5, erosion=0.01, min_extent=0.05, outgrow=0.2)
    assert new.defined
    np.testing.assert_allclose(extent(new), [-1.19, -0.45, 0.0, 0.35, 0.45, 0.8], atol=1e-6)
    # The other mixed case: a small Defined detection against a partial object reaching beyond it.
    new = integrate_box(whole, partial, 1, 5, erosion=0.01, min_extent=0.05, outgrow=0.2)
    assert new.defined
    np.testing.assert_allclose(extent(new), [-1.19, -0.45, 0.0, 0.35, 0.45, 0.8], atol=1e-6)


@pytest.mark.parametrize("partial, outgrow, grows", [
    (box(-0.5, 0.3, False), 0.2, False),   # 0.15 m beyond: within the margin, the paper's rule
    (box(-0.6, 0.3, False), 0.2, True),    # 0.25 m beyond
    (box(-1.2, 0.3, False), None, False),  # the paper: a partial view never changes a Defined box
])
def test_the_margin_decides(partial, outgrow, grows):
    whole = box(-0.35, 0.35, True)
    new = integrate_box(partial, whole, 1, 5, 0.01, 0.05, outgrow)
    assert bool(extent(new)[0] < -0.36) is grows
    if not grows:
        np.testing.assert_allclose(extent(new), extent(whole))


def test_the_grown_box_keeps_the_defined_orientation():
    """The Defined box turned 90 degrees (x -0.45-0.45, y -0.35-0.35 in the world) and a partial box
    over x -0.4-0.4, y 0.1-0.6 reaching 0.25 m beyond it along y: the box keeps yaw 90 degrees and
    grows to world y -0.35-0.59; world x stays -0.45-0.45."""
    turned = Box(np.array([0.0, 0.0, 0.4]), np.pi / 2, np.array([0.7, 0.9, 0.8]), np.ones(8, bool), True)
    new = integrate_box(box(-0.4, 0.4, False, 0.1, 0.6), turned, 1, 5, 0.01, 0.05, 0.2)
    assert new.yaw == pytest.approx(np.pi / 2)
    np.testing.assert_allclose(extent(new), [-0.45, -0.35, 0.0, 0.45, 0.59, 0.8], atol=1e-6)
    np.testing.assert_allclose(new.size, [0.94, 0.9, 0.8], atol=1e-6)


@pytest.mark.parametrize("a_deg, b_deg, turn_deg", [
    (0, 0, 0), (10, 0, 10), (0, 37, 37), (80, 0, 10), (90, 0, 0), (-89, 0, 1), (45, 0, 45), (60, -30, 0),
    (-80, 85, 15),  # -80 against 85: 165 degrees apart, 15 from the quarter turn at 180
])
def test_square_turn_by_hand(a_deg, b_deg, turn_deg):
    assert np.degrees(square_turn(np.radians(a_deg), np.radians(b_deg))) == pytest.approx(turn_deg, abs=1e-9)


@pytest.mark.parametrize("turn_deg, max_turn_deg, grows", [
    (10, 15, True), (20, 15, False), (37, 15, False), (80, 15, True),  # 80 is 10 modulo 90
    (37, None, True),  # no limit: the seventeenth round's rule
])
def test_a_partial_box_turned_too_far_does_not_grow_the_defined_box(turn_deg, max_turn_deg, grows):
    """A 0.7 x 0.9 m Defined couch piece at the origin and a 1.5 x 0.5 m partial box centred at
    x -0.6, turned by ``turn_deg``: it reaches at least 0.45 m past x -0.35 at every turn tried
    (its far end's middle alone lies at x -0.6 - 0.75 cos t), so only the turn decides."""
    whole = box(-0.35, 0.35, True)
    t = np.radians(turn_deg)
    partial = Box(np.array([-0.6, 0.0, 0.4]), float(t), np.array([1.5, 0.5, 0.8]), np.ones(8, bool), False)
    assert reach_beyond(partial, whole) > 0.2
    limit = None if max_turn_deg is None else np.radians(max_turn_deg)
    new = integrate_box(partial, whole, 1, 5, 0.01, 0.05, 0.2, limit)
    assert bool(extent(new)[0] < -0.36) is grows
    assert new.yaw == whole.yaw
    if not grows:
        np.testing.assert_allclose(extent(new), extent(whole))


def test_a_merge_of_two_objects_grows_the_same_way():
    s = np.array([0.8, 0.1, 0.0, 0.1])
    new, _ = merge_objects(box(-0.35, 0.35, True), box(-1.2, 0.3, False), s, s, 5, 5, 0.01, 0.05, 0.2)
    np.testing.assert_allclose(extent(new), [-1.19, -0.45, 0.0, 0.35, 0.45, 0.8], atol=1e-6)


def arrays(*boxes):
    return (np.array([b.center for b in boxes]), np.array([b.yaw for b in boxes]),
            np.array([b.size for b in boxes]))


def test_shares_inside_by_hand():
    """A unit cube x, y, z 0-1 holds half of a cube shifted 0.5 along x, a quarter of one shifted
    0.5 along x and z, half of the first one turned 90 degrees (the same square), none of a far one."""
    cube = Box(np.array([0.5, 0.5, 0.5]), 0.0, np.ones(3), np.ones(8, bool), True)
    others = [Box(np.array([1.0, 0.5, 0.5]), 0.0, np.ones(3), np.ones(8, bool), True),
              Box(np.array([1.0, 0.5, 1.0]), 0.0, np.ones(3), np.ones(8, bool), True),
              Box(np.array([1.0, 0.5, 0.5]), np.pi / 2, np.ones(3), np.ones(8, bool), True),
              Box(np.array([5.0, 0.5, 0.5]), 0.0, np.ones(3), np.ones(8, bool), True)]
    np.testing.assert_allclose(shares_inside(cube, *arrays(*others)), [0.5, 0.25, 0.5, 0.0], atol=1e-9)


def test_takes_in_by_hand():
    """A box grown from x 0-0.6 to 0-1 (y -0.45-0.45) takes in a chair over x 0.7-1.1 (3/4 of it now
    inside, none before), not one over x 0.9-1.3 (a quarter inside)."""
    before, grown = box(0.0, 0.6, True), box(0.0, 1.0, True)
    assert takes_in(grown, before, *arrays(box(0.7, 1.1, True, -0.2, 0.2)))
    assert not takes_in(grown, before, *arrays(box(0.9, 1.3, True, -0.2, 0.2)))
    assert not takes_in(grown, grown, *arrays(box(0.7, 1.1, True, -0.2, 0.2)))  # inside already


def mapper_with_couch(cfg, chair_at=None):
    smap = SemanticMap.new(CLASSES)
    if chair_at is not None:
        chair = box(chair_at, chair_at + 0.4, True, -0.2, 0.2)
        smap.objects.append(center=chair.center, yaw=0.0, size=chair.size, visible=np.ones(8, bool),
                            defined=True, scores=np.array([0.0, 0.05, 0.9, 0.05]), n_det=5, status=ACTIVE,
                            first_session=0, last_session=0)
    whole = box(-0.35, 0.35, True)
    row = smap.objects.append(center=whole.center, yaw=0.0, size=whole.size, visible=np.ones(8, bool),
                              defined=True, scores=np.array([0.9, 0.05, 0.0, 0.05]), n_det=5, status=ACTIVE,
                              first_session=0, last_session=0)
    mapper = Mapper(smap, cfg, plugins.get("metrics", "vertex").factory(cfg["association"]),
                    plugins.get("policies", "non-detection").factory(cfg["maintenance"]), session=0)
    return mapper, row


@pytest.mark.parametrize("chair_at, grows", [
    (-1.0, False),  # a chair over x -1.0 - -0.6 would lie inside the grown couch: no growth
    (-1.5, True),   # x -1.5 - -1.1: a quarter inside it, the couch grows
])
def test_the_mapper_never_grows_a_box_over_another_object(chair_at, grows):
    mapper, row = mapper_with_couch(defaults(), chair_at)
    mapper._integrate(row, box(-1.2, 0.3, False), np.array([0.8, 0.1, 0.0, 0.1]), 0, "0")
    assert mapper.map.objects.size[row].max() == pytest.approx(1.54 if grows else 0.9)


@pytest.mark.parametrize("object_scores, det_scores, grows", [
    ([0.9, 0.05, 0.0, 0.05], [0.8, 0.1, 0.0, 0.1], True),    # a couch view of the couch
    ([0.9, 0.05, 0.0, 0.05], [0.1, 0.8, 0.0, 0.1], False),   # a "bed" view: another class never reshapes it
    ([0.0, 0.05, 0.9, 0.05], [0.0, 0.1, 0.8, 0.1], False),   # a chair: not in the default classes
])
def test_the_mapper_grows_only_by_views_of_its_own_class(object_scores, det_scores, grows):
    cfg = defaults()
    cfg["association"]["other_class_volume_ratio"] = None  # the bed view is not foreign by volume
    mapper, row = mapper_with_couch(cfg)
    mapper.map.objects.cols["scores"][row] = object_scores
    mapper._integrate(row, box(-1.2, 0.3, False), np.array(det_scores), 0, "0")
    t = mapper.map.objects
    assert t.size[row].max() == pytest.approx(1.54 if grows else 0.9)
    assert bool(t.defined[row])


def test_default_and_paper():
    assert defaults()["integration"]["partial_outgrow"] == {"couch": 0.2, "bed": 0.2, "dining table": 0.2,
                                                            "refrigerator": 0.2}
    paper = yaml.safe_load((Path(__file__).resolve().parent.parent / "docs" / "paper.yaml").read_text())
    assert paper["integration"]["partial_outgrow"] is None
    assert defaults()["integration"]["partial_outgrow_turn"] == 15
    assert paper["integration"]["partial_outgrow_turn"] is None


def test_one_class_can_be_turned_off():
    """The user's {couch: null} merges into the defaults: the couch keeps the paper's rule, the
    other classes keep theirs."""
    from ltc_cli.config import load_config

    cfg = load_config(None, ["integration.partial_outgrow={couch: null}"])
    assert cfg["integration"]["partial_outgrow"]["couch"] is None
    assert cfg["integration"]["partial_outgrow"]["bed"] == 0.2
    mapper, row = mapper_with_couch(cfg)
    mapper._integrate(row, box(-1.2, 0.3, False), np.array([0.8, 0.1, 0.0, 0.1]), 0, "0")
    assert mapper.map.objects.size[row].max() == pytest.approx(0.9)


@pytest.mark.parametrize("overrides, grows", [([], False), (["integration.partial_outgrow_turn=null"], True),
                                              (["integration.partial_outgrow_turn=40"], True)])
def test_the_mapper_applies_the_turn_limit_from_config(overrides, grows):
    """A couch view over x -1.35 - 0.15 turned 30 degrees: the default 15-degree limit keeps the
    Defined box; with no limit, or a 40-degree one, it grows past x -0.35."""
    from ltc_cli.config import load_config

    mapper, row = mapper_with_couch(load_config(None, overrides))
    partial = Box(np.array([-0.6, 0.0, 0.4]), float(np.radians(30)), np.array([1.5, 0.5, 0.8]), np.ones(8, bool), False)
    mapper._integrate(row, partial, np.array([0.8, 0.1, 0.0, 0.1]), 0, "0")
    t = mapper.map.objects
    assert bool(extent(t.box(row))[0] < -0.36) is grows

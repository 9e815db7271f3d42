"""modeling.higher_than (issue 9, twenty-fourth round): a toilet stands on the floor, so a "toilet"
whose bottom is high above the floor (a sink in a counter) is the class its detector scored second. Expected values worked out by
hand from the rendered scene (tests/scene.py: camera at (0, 0, 1) looking along +x, z up, floor at
z 0)."""

import numpy as np
import pytest

from ltc_cli.config import defaults
from ltc_cli.map.model import top_class
from ltc_cli.pipeline.frame_modeling import NEXT, ClassFlags, model_frame
from tests.scene import INTR, T_world_camera, render

CLASSES = ["toilet", "sink", "chair"]  # then other


def toilet_vector():
    return np.array([0.6, 0.3, 0.05, 0.05])  # toilet 0.6, sink second


def sink_vector():
    return np.array([0.3, 0.6, 0.05, 0.05])  # sink 0.6, toilet second


def test_relabel_by_floor_gap_by_hand():
    """toilet never higher than 0.45 m: a toilet 0.7 m up gives its 0.6 to sink (0.9); 0.2 m up,
    or with no floor height (NaN), it stays; a sink 0.7 m up stays; a toilet 0.7 m up with no second
    class stays (nothing says what else it is)."""
    from ltc_cli.pipeline.frame_modeling import relabel_too_tall

    alone = np.array([1.0, 0.0, 0.0, 0.0])
    scores = [toilet_vector(), toilet_vector(), toilet_vector(), sink_vector(), alone]
    out = relabel_too_tall(scores, np.arange(5), np.array([0.7, 0.2, np.nan, 0.7, 0.7]),
                           np.array([0.45, np.inf, np.inf, np.inf]), np.array([NEXT, -1, -1, -1]))
    assert out[0] == pytest.approx([0.0, 0.9, 0.05, 0.05])
    for k in (1, 2, 3, 4):
        assert out[k] == pytest.approx(scores[k])


def test_floor_gap_bounds_from_settings():
    cfg = defaults()
    assert cfg["modeling"]["higher_than"] == {"toilet": {"gap": 0.45, "is": "next"}}
    flags = ClassFlags.from_settings(CLASSES, cfg)
    assert flags.max_gap.tolist() == [0.45, np.inf, np.inf, np.inf]
    assert flags.higher_is.tolist() == [NEXT, -1, -1, -1]
    flags = ClassFlags.from_settings(["sink", "chair"], cfg)  # no toilet in the map: nothing to judge
    assert flags.max_gap.tolist() == [np.inf, np.inf, np.inf]


def stage_1(z0, z1, vector, cfg, floor_z=0.0):
    """One 0.5 m wide, 0.3 m deep block 2 m ahead, from z0 to z1 (under the camera's 1.0 m)."""
    depth, masks = render([(2.0, 2.3, -0.25, 0.25, z0, z1)], wall_x=4.0)
    return model_frame(masks, [vector], depth, T_world_camera(), INTR, (0.3, 6.0), cfg,
                       ClassFlags.from_settings(CLASSES, cfg), floor_z=floor_z)


@pytest.mark.parametrize("z0, vector, rules, floor_z, expected, bottom", [
    (0.6, toilet_vector(), True, 0.0, "sink", 0.6),     # a "toilet" 0.6 m up: sink, not grounded
    (0.6, toilet_vector(), False, 0.0, "toilet", 0.0),  # {}: a toilet, grounded to the floor
    (0.6, toilet_vector(), True, None, "toilet", 0.6),  # no floor height: nothing judged
    (0.1, toilet_vector(), True, 0.0, "toilet", 0.0),   # a toilet on the floor
    (0.6, sink_vector(), True, 0.0, "sink", 0.6),       # a sink at counter height
    (0.05, sink_vector(), True, 0.0, "sink", 0.05),     # sinks are not judged (their masks bleed
                                                        # onto the cabinet below)
])
def test_stage_1_judges_toilets_and_sinks_by_their_height_above_the_floor(z0, vector, rules, floor_z,
                                                                           expected, bottom):
    """The block from z0 to 0.95 m. Toilet is a floor class: grounded (bottom at the floor) unless
    higher_than says it is no toilet; a sink is not a floor class."""
    cfg = defaults()
    assert "toilet" in cfg["modeling"]["floor_classes"]
    if not rules:
        cfg["modeling"]["higher_than"] = {}
    out = stage_1(z0, 0.95, vector, cfg, floor_z)
    assert len(out.modeled.source) == 1
    assert CLASSES[int(top_class(out.scores[0]))] == expected
    box = out.modeled.boxes
    assert box.center[0, 2] - box.size[0, 2] / 2 == pytest.approx(bottom, abs=0.04)
    if floor_z is None:
        assert np.isnan(out.modeled.bottom_gap).all()
    else:
        assert out.modeled.bottom_gap[0] == pytest.approx(z0 - floor_z, abs=0.04)


# modeling.top_under: a refrigerator stands taller than a counter, and a basin stands at counter height.
KITCHEN = ["refrigerator", "oven", "chair"]  # then other


def fridge_vector():
    return np.array([0.6, 0.3, 0.05, 0.05])  # refrigerator 0.6, oven second


def test_relabel_low_tops_by_hand():
    """Floor at z 0.1; bound: a refrigerator's seen top never under 1.2 m above it. Box tops (z)
    1.05 (0.95 up, a top corner visible and the mask ending against the wall: oven, its 0.6 moves
    to 0.9), 1.05 with no top corner visible (not seen, not judged), 1.9 (1.8 up: stays), an oven
    1.05 (no bound: stays)."""
    from ltc_cli.geometry.boxes import Boxes
    from ltc_cli.pipeline.frame_modeling import relabel_low_tops, seen_tops
    from ltc_cli.pipeline.modeling import ModeledDetections

    flags = ClassFlags(np.zeros(4, bool), np.zeros(4, bool), np.full(4, np.nan),
                       min_top=np.array([1.2, -np.inf, -np.inf, -np.inf]), top_under_is=np.array([NEXT, -1, -1, -1]))
    visible = np.zeros((4, 8), bool)
    visible[[0, 2, 3], 5] = True  # one top corner of boxes 0, 2 and 3
    visible[1, :4] = True         # box 1: only its bottom corners
    boxes = Boxes(np.array([[0, 0, 0.6], [0, 0, 0.6], [0, 0, 1.0], [0, 0, 0.6]]), np.zeros(4),
                  np.array([[0.6, 0.6, 0.9], [0.6, 0.6, 0.9], [0.7, 0.7, 1.8], [0.6, 0.6, 0.9]]), visible)
    oven = np.array([0.3, 0.6, 0.05, 0.05])
    scores = [fridge_vector(), fridge_vector(), fridge_vector(), oven]
    modeled = ModeledDetections(boxes, np.zeros(4, bool), np.arange(4), np.full(4, 100))
    # Every mask ends against a wall 1 m behind (the background test passes).
    masks = [np.pad(np.ones((20, 10), bool), ((30, 30), (5, 5)))] * 4
    depth = np.where(masks[0], 2.0, 3.0)
    heights, seen = seen_tops(modeled, masks, depth, 0.1, np.array([1.2, 1.2, 1.2, -np.inf]))
    assert heights == pytest.approx([0.95, 0.95, 1.8, 0.95]) and seen.tolist() == [True, False, True, True]
    out = relabel_low_tops(scores, np.arange(4), heights, seen, flags)
    assert out[0] == pytest.approx([0.0, 0.9, 0.05, 0.05])
    for k in (1, 2, 3):
        assert out[k] == pytest.approx(scores[k])


@pytest.mark.parametrize("above, expected", [
    (3.0, True),    # the wall 1 m behind the object above its mask: its top
    (2.05, False),  # more of the object (5 cm deeper) above the mask: a cut, not a top
    (0.0, False),   # no depth above it (a hole on a shiny door)
])
def test_top_in_view_by_hand(above, expected):
    """A 20 x 10 px mask at depth 2 m starting at row 30: rows 18-27 above it hold ``above``."""
    from ltc_cli.pipeline.frame_modeling import top_in_view

    mask = np.zeros((80, 20), bool)
    mask[30:50, 5:15] = True
    depth = np.full((80, 20), 3.0)
    depth[mask] = 2.0
    depth[18:28, :] = above
    assert top_in_view(mask, depth) is expected
    # A mask touching the image's top edge has nothing above it.
    assert top_in_view(np.roll(mask, -30, axis=0), depth) is False


@pytest.mark.parametrize("z1, rule, expected", [
    (0.95, True, "oven"),            # a "refrigerator" whose top is seen 0.95 m up
    (1.8, True, "refrigerator"),     # 1.8 m: a refrigerator
    (0.95, False, "refrigerator"),   # top_under {}: the paper
])
def test_stage_1_calls_a_low_refrigerator_its_next_class(z1, rule, expected):
    """A 0.6 m wide, 0.6 m deep block 2 m ahead from the floor to z1, in full view (its front top
    corners on the face the camera sees)."""
    cfg = defaults()
    assert cfg["modeling"]["top_under"]["refrigerator"] == {"height": 1.2, "is": "next"}
    if not rule:
        cfg["modeling"]["top_under"] = {}
    depth, masks = render([(2.0, 2.6, -0.3, 0.3, 0.0, z1)], wall_x=4.0)
    out = model_frame(masks, [fridge_vector()], depth, T_world_camera(), INTR, (0.3, 6.0), cfg,
                      ClassFlags.from_settings(KITCHEN, cfg), floor_z=0.0)
    assert len(out.modeled.source) == 1 and out.modeled.boxes.visible[0, 4:].any()
    assert KITCHEN[int(top_class(out.scores[0]))] == expected


@pytest.mark.parametrize("z0, z1, vector, rule, expected", [
    (0.0, 0.75, sink_vector(), True, "toilet"),    # a "sink" whose top is seen 0.75 m up: a toilet
    (0.0, 0.95, sink_vector(), True, "sink"),      # a pedestal basin, its top 0.95 m up
    (0.7, 0.95, sink_vector(), True, "sink"),      # a basin in a counter
    (0.0, 0.75, sink_vector(), False, "sink"),     # top_under without sink: the basin stays
    (0.0, 0.75, toilet_vector(), True, "toilet"),  # a toilet is not judged by its top
])
def test_stage_1_calls_a_low_sink_its_next_class(z0, z1, vector, rule, expected):
    """A 0.5 m wide, 0.5 m deep block 2 m ahead from z0 to z1 (floor at z 0), its top in full view
    against the wall 2 m behind; "sink" 0.6 with "toilet" second (or the other way round)."""
    cfg = defaults()
    assert cfg["modeling"]["top_under"]["sink"] == {"height": 0.8, "is": "next"}
    if not rule:
        del cfg["modeling"]["top_under"]["sink"]
    depth, masks = render([(2.0, 2.5, -0.25, 0.25, z0, z1)], wall_x=4.0)
    out = model_frame(masks, [vector], depth, T_world_camera(), INTR, (0.3, 6.0), cfg,
                      ClassFlags.from_settings(CLASSES, cfg), floor_z=0.0)
    assert len(out.modeled.source) == 1 and out.modeled.boxes.visible[0, 4:].any()
    assert CLASSES[int(top_class(out.scores[0]))] == expected


# modeling.floor_min_top: no piece of furniture that stands on the floor is under 0.3 m tall.
def test_drop_floor_blobs_by_hand():
    """Floor at z 0.1, bound 0.3 m. Box tops 0.3 (0.2 above the floor: dropped), 0.95 (0.85:
    kept), 0.4 (0.3 exactly: kept, not under), and a low box of a class not on the floor (a book
    lying there, top 0.2: kept)."""
    from ltc_cli.geometry.boxes import Boxes
    from ltc_cli.pipeline.frame_modeling import drop_floor_blobs
    from ltc_cli.pipeline.modeling import ModeledDetections

    sizes = np.array([[1.5, 0.7, 0.2], [0.5, 0.5, 0.9], [0.5, 0.5, 0.3], [0.2, 0.15, 0.1]])
    boxes = Boxes(np.array([[0, 0, 0.2], [1, 0, 0.5], [2, 0, 0.25], [3, 0, 0.15]]), np.zeros(4), sizes,
                  np.zeros((4, 8), bool))
    modeled = ModeledDetections(boxes, np.zeros(4, bool), np.arange(4), np.full(4, 100))
    out = drop_floor_blobs(modeled, np.array([True, True, True, False]), 0.1, 0.3)
    assert out.source.tolist() == [1, 2, 3]
    assert out.boxes.center[:, 0].tolist() == [1, 2, 3]


def chair_vector():
    return np.array([0.05, 0.05, 0.85, 0.05])


@pytest.mark.parametrize("z1, min_top, floor_z, boxes", [
    (0.2, 0.3, 0.0, 0),     # a "chair" 0.2 m high on the floor: the floor, no box
    (0.2, None, 0.0, 1),    # the rule off: a box
    (0.2, 0.3, None, 1),    # no floor height: nothing judged
    (0.2, 0.3, -0.2, 1),    # the floor 0.2 m lower: its top is 0.4 m above it
    (0.9, 0.3, 0.0, 1),     # a chair's height
])
def test_stage_1_drops_a_chair_box_at_floor_level(z1, min_top, floor_z, boxes):
    """The 0.5 x 0.3 m block 2 m ahead from the floor (z 0) to z1, called chair (a floor class)."""
    cfg = defaults()
    assert "chair" in cfg["modeling"]["floor_classes"] and cfg["modeling"]["floor_min_top"] == 0.3
    cfg["modeling"]["floor_min_top"] = min_top
    out = stage_1(0.0, z1, chair_vector(), cfg, floor_z)
    assert len(out.modeled.source) == boxes

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

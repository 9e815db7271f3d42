"""association.stand_inside_parts (issue 9, thirty-third round): a "mouse" inside the floor of a "tv"
box is the monitor's foot, because modeling.taller_than takes a tall "mouse" for a tv; a keyboard
there is not. tum-fr1-rpy read backwards with the int8 model: the front monitor's box reached the
desk and its foot's plate lay inside it, 5 mm above its bottom. Values worked out by hand."""

import numpy as np
import pytest

from ltc_cli import plugins
from ltc_cli.config import load_config
from ltc_cli.geometry.boxes import Boxes
from ltc_cli.map.model import ACTIVE, MERGED, SemanticMap
from ltc_cli.pipeline.frame_modeling import ClassFlags
from ltc_cli.pipeline.mapper import Mapper
from ltc_cli.pipeline.stands import stand_pairs
from tests.scene import INTR, T_world_camera

CLASSES = ["tv", "mouse", "keyboard"]  # then other
TV, MOUSE, KEYBOARD = 0, 1, 2
# The screen's box: x 2.07..2.33, y -0.30..0.30, z 0.725..1.235 (0.51 tall). The plate: x 2.13..2.31,
# y -0.125..0.165, z 0.73..0.79: its bottom 0.005 above the screen box's, its top 0.065 above it.
SCREEN = ([2.2, 0.0, 0.98], [0.26, 0.6, 0.51])
PLATE = ([2.22, 0.02, 0.76], [0.18, 0.29, 0.06])


def boxes(*pairs) -> Boxes:
    return Boxes(np.array([c for c, _ in pairs], float), np.zeros(len(pairs)), np.array([s for _, s in pairs], float),
                 np.ones((len(pairs), 8), bool))


def pairs(lower_class, part_of, plate=PLATE):
    """stand_pairs with the defaults' stand_gap 0.08, margin 0.1, low 0.3, centred 0.25, within 0.5."""
    return stand_pairs(boxes(SCREEN, plate), np.array([TV, lower_class]), 0.08, 0.1, low=0.3, centred=0.25,
                       within=0.5, part_of=part_of)


def test_taller_than_gives_what_a_mouse_is_part_of():
    taller_is = ClassFlags.from_settings(CLASSES, load_config(None, [])).taller_is
    assert taller_is[MOUSE] == TV       # modeling.taller_than: mouse over 0.12 m is tv
    assert taller_is[KEYBOARD] == -1    # nothing for a keyboard


def test_a_mouse_inside_the_screens_floor_is_its_foot():
    """The plate's top 0.065 m over the screen box's bottom (within stand_gap 0.08), 0.06 m tall
    (under 0.3 x 0.51), its centre 0.02 m from the screen's in both axes (within half its sides):
    all that the stand rule asks, but for its bottom, 0.005 m above the screen box's."""
    part_of = ClassFlags.from_settings(CLASSES, load_config(None, [])).taller_is
    assert [(a, b) for _, a, b in pairs(MOUSE, part_of)] == [(0, 1)]
    assert pairs(MOUSE, part_of)[0][0] == pytest.approx(0.065)
    assert pairs(MOUSE, None) == []                       # without: the bottom must lie lower
    assert pairs(KEYBOARD, part_of) == []                 # a keyboard is no part of a tv
    # 0.09 above the screen box's bottom (over stand_gap): a thing on something inside the box.
    assert pairs(MOUSE, part_of, ([2.22, 0.02, 0.845], [0.18, 0.29, 0.06])) == []


def after_one_frame(overrides, objects):
    """A mapper (static policy) over a map of axis-aligned objects ((center, size), class, Defined,
    detections), each 0.9 on its class, after one frame with no detections that has them in view:
    (mapper, the frame's result)."""
    cfg = load_config(None, list(overrides))
    smap = SemanticMap.new(CLASSES)
    for (center, size), cls, defined, n in objects:
        v = np.full(len(CLASSES) + 1, 0.05)
        v[cls], v[-1] = 0.9, 0.0
        smap.objects.append(center=np.array(center), yaw=0.0, size=np.array(size), visible=np.ones(8, bool),
                            defined=defined, scores=v / v.sum(), n_det=n, status=ACTIVE, first_session=0,
                            last_session=0)
    mapper = Mapper(smap, cfg, plugins.get("metrics", "vertex").factory(cfg["association"]),
                    plugins.get("policies", "static").factory(cfg["maintenance"]), session=0)
    depth = np.full((INTR.height, INTR.width), 4.0, np.float32)
    return mapper, mapper.process_frame(0, "0", [], [], depth, T_world_camera(), INTR, (0.3, 6.0))


@pytest.mark.parametrize("overrides, lower_class, merged", [
    ((), MOUSE, True),
    (("association.stand_inside_parts=false",), MOUSE, False),
    ((), KEYBOARD, False),
])
def test_through_the_mapper(overrides, lower_class, merged):
    mapper, res = after_one_frame(overrides, [(SCREEN, TV, True, 30), (PLATE, lower_class, True, 10)])
    assert list(mapper.map.objects.status[:2]) == ([ACTIVE, MERGED] if merged else [ACTIVE, ACTIVE])
    assert res.merged == int(merged)


# The same screen as a partial "tv" box, 0.6 x 0.27 x 0.39 m (x 2.065..2.335, y -0.30..0.30,
# z 0.855..1.245), and its foot and neck, a Defined "tv" (taller_than) 0.17 x 0.31 x 0.19 m under it
# (x 2.135..2.305, y -0.135..0.175, z 0.685..0.875): tum-fr1-rpy read with int8, odd frames
# backwards then the even ones, frame 212. Its top 0.02 m over the screen box's bottom, its
# centre (2.22, 0.02) 0.02 from the screen's along both sides, 0.19 m tall: under half the
# screen's 0.39 and in its lower half (stand_centred).
PARTIAL_SCREEN = ([2.2, 0.0, 1.05], [0.27, 0.6, 0.39])
FOOT_AND_NECK = ([2.22, 0.02, 0.78], [0.17, 0.31, 0.19])


@pytest.mark.parametrize("part_under", [True, False])
def test_a_defined_foot_under_a_partial_screen_of_its_class_is_a_piece_of_it(part_under):
    """Both "tv", they merge (eq. 2 over the 8 vertices under 0.4 m; the foot's footprint wholly
    in the screen's). With merge_part_under the merged box encloses both: the screen's footprint,
    z 0.685..1.245. Without, the Defined foot replaces the partial screen (DESIGN 1.3), as it did."""
    overrides = [f"association.merge_part_under={'true' if part_under else 'false'}"]
    mapper, res = after_one_frame(overrides, [(PARTIAL_SCREEN, TV, False, 30), (FOOT_AND_NECK, TV, True, 2)])
    t = mapper.map.objects
    assert res.merged == 1 and list(t.status[:2]) == [ACTIVE, MERGED]
    bottom, top = t.center[0, 2] - t.size[0, 2] / 2, t.center[0, 2] + t.size[0, 2] / 2
    if part_under:
        assert (bottom, top) == (pytest.approx(0.685, abs=0.02), pytest.approx(1.245, abs=0.02))
        assert t.size[0, :2].max() == pytest.approx(0.6, abs=0.03)
    else:
        assert (bottom, top) == (pytest.approx(0.685, abs=1e-6), pytest.approx(0.875, abs=1e-6))

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


@pytest.mark.parametrize("overrides, lower_class, merged", [
    ((), MOUSE, True),
    (("association.stand_inside_parts=false",), MOUSE, False),
    ((), KEYBOARD, False),
])
def test_through_the_mapper(overrides, lower_class, merged):
    cfg = load_config(None, list(overrides))
    smap = SemanticMap.new(CLASSES)
    for (center, size), cls, n in ((SCREEN, TV, 30), (PLATE, lower_class, 10)):
        v = np.full(len(CLASSES) + 1, 0.05)
        v[cls], v[-1] = 0.9, 0.0
        smap.objects.append(center=np.array(center), yaw=0.0, size=np.array(size), visible=np.ones(8, bool),
                            defined=True, scores=v / v.sum(), n_det=n, status=ACTIVE, first_session=0,
                            last_session=0)
    mapper = Mapper(smap, cfg, plugins.get("metrics", "vertex").factory(cfg["association"]),
                    plugins.get("policies", "static").factory(cfg["maintenance"]), session=0)
    depth = np.full((INTR.height, INTR.width), 4.0, np.float32)
    res = mapper.process_frame(0, "0", [], [], depth, T_world_camera(), INTR, (0.3, 6.0))
    assert list(mapper.map.objects.status[:2]) == ([ACTIVE, MERGED] if merged else [ACTIVE, ACTIVE])
    assert res.merged == int(merged)

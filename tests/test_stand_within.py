"""A stand's footprint centre lies inside its screen's footprint (association stand_within; issue 9,
thirty-first round). On tum-fr1-rpy read backwards a front monitor box grown 0.36-0.38 m deep took
the keyboard and the white mouse in front of it as its feet (under its footprint grown by
stand_margin, their tops within stand_gap of its bottom), and the second monitor's foot, standing
out in front of its screen's box, stayed a "mouse". Expected values are worked out by hand."""

import numpy as np
import pytest

from ltc_cli.config import defaults
from ltc_cli.geometry.boxes import Boxes
from ltc_cli.map.model import ACTIVE, MERGED, SemanticMap
from ltc_cli.pipeline.stands import centred_under, stand_pairs
from tests.test_identity import CLASSES
from tests.test_stand_merge import class_vector, empty_frame

TV, MOUSE, KEYBOARD = 1, 2, 3

# All yaw 0. The screen, 0.3 deep along x and 0.5 long along y:
# 0 tv       x 2.05..2.35  y -0.25..0.25  z 0.80..1.20
# 1 keyboard x 2.33..2.53  y -0.20..0.20  z 0.74..0.78  in front of it: its top 0.02 under the
#            screen's bottom, 0.04 tall (0.1 of the screen, under stand_low 0.3); of its x extent
#            2.33..2.53, 2.33..2.45 lies under the screen grown by 0.1 (1.95..2.45): 0.6 of its
#            footprint; its centre x 2.43 is 0.28 from the screen's, 0.93 of the 0.3 depth.
# 2 mouse    x 2.15..2.29  y -0.12..0.12  z 0.76..0.79  a foot: its centre 0.02 from the screen's
#            along x (0.07 of the depth), wholly under the screen's footprint.
GAP_CENTER = [[2.2, 0.0, 1.0], [2.43, 0.0, 0.76], [2.22, 0.0, 0.775]]
GAP_SIZE = [[0.3, 0.5, 0.4], [0.2, 0.4, 0.04], [0.14, 0.24, 0.03]]

# The centred path: the screen's box reaches the desk and the foot stands inside it, out in front.
# 0 tv    as above
# 1 mouse x 2.24..2.44  y -0.05..0.09  z 0.78..0.94: 0.16 tall (0.4 of the screen: over stand_low),
#         its top 0.14 above the screen's bottom (over stand_gap 0.05), in its lower half; its centre
#         (2.34, 0.02) is 0.14 / 0.3 = 0.47 of the depth and 0.02 / 0.5 = 0.04 of the length from
#         the screen's centre: not within stand_centred 0.25 across, within 0.5.
# 2 mouse the same 0.19 along y: 0.38 of the length (a mug by the screen's end, as in
#         test_stand_merge.py): beyond stand_centred 0.25 along.
OUT_CENTER = [[2.2, 0.0, 1.0], [2.34, 0.02, 0.86], [2.34, 0.19, 0.86]]
OUT_SIZE = [[0.3, 0.5, 0.4], [0.2, 0.14, 0.16], [0.2, 0.14, 0.16]]


def make_boxes(center, size, yaw=0.0) -> Boxes:
    return Boxes(np.array(center, float), np.full(len(center), yaw), np.array(size, float),
                 np.ones((len(center), 8), bool))


def pairs_of(boxes, top, **kw):
    return sorted((a, b) for _, a, b in stand_pairs(boxes, np.array(top), 0.05, 0.1, low=0.3, **kw))


def test_a_keyboard_in_front_of_the_screen_is_not_its_foot():
    boxes = make_boxes(GAP_CENTER, GAP_SIZE)
    top = [TV, KEYBOARD, MOUSE]
    assert pairs_of(boxes, top) == [(0, 1), (0, 2)]               # under the grown footprint: both
    assert pairs_of(boxes, top, within=0.5) == [(0, 2)]           # centre inside the footprint: the foot
    assert pairs_of(boxes, top, within=0.95) == [(0, 1), (0, 2)]  # 0.93 of the depth is within 0.95


def test_a_foot_out_in_front_inside_a_screen_box_reaching_the_desk():
    boxes = make_boxes(OUT_CENTER, OUT_SIZE)
    top = [TV, MOUSE, MOUSE]
    assert pairs_of(boxes, top, centred=0.25) == []
    assert pairs_of(boxes, top, centred=0.25, within=0.5) == [(0, 1)]  # the mug by the end stays out
    assert pairs_of(boxes, top, centred=0.25, within=0.45) == []        # 0.47 of the depth


def test_centred_under_measures_along_the_longer_side_whatever_the_axes():
    """The screen 0.5 long along world y, as a box 0.5 long on its own y axis (yaw 0) or on its own
    x axis turned 90 degrees: the same footprint, so the same answer. A centre (0.13, 0.02) from
    the screen's is 0.02 / 0.5 = 0.04 of its length along it and 0.13 / 0.3 = 0.43 of its depth."""
    for yaw, size in ((0.0, [0.3, 0.5, 0.4]), (np.pi / 2, [0.5, 0.3, 0.4])):
        b = Boxes(np.array([[0.13, 0.02, 0.05], [0.0, 0.0, 0.2]]), np.array([0.0, yaw]),
                  np.array([[0.05, 0.05, 0.1], size]), np.ones((2, 8), bool))
        assert bool(centred_under(b, 0.25, 0.5)[0, 1])
        assert not bool(centred_under(b, 0.25, 0.4)[0, 1])
        assert not bool(centred_under(b, 0.25)[0, 1])  # 0.43 of the depth against 0.25 on both axes


@pytest.mark.parametrize("within", [None, 0.5])
def test_through_the_mapper_the_keyboard_stays_and_the_foot_joins(within):
    """The screen (40 detections), the keyboard in front (30) and the foot (60) of GAP_* in view of a
    frame with no detections (static policy): the foot merges into the screen either way; the
    keyboard only without stand_within."""
    cfg = defaults()
    cfg["association"]["stand_within"] = within
    smap = SemanticMap.new(CLASSES)
    for i, (cls, n_det) in enumerate(((TV, 40), (KEYBOARD, 30), (MOUSE, 60))):
        smap.objects.append(center=np.array(GAP_CENTER[i], float), yaw=0.0, size=np.array(GAP_SIZE[i], float),
                            visible=np.ones(8, bool), defined=True, scores=class_vector(cls), n_det=n_det,
                            status=ACTIVE)
    mapper, _ = empty_frame(smap, cfg, session=0)
    status = list(mapper.map.objects.status[:3])
    assert status == ([ACTIVE, MERGED, MERGED] if within is None else [ACTIVE, ACTIVE, MERGED])
    np.testing.assert_allclose(mapper.map.objects.size[0], GAP_SIZE[0])


@pytest.mark.parametrize("plate_top, joins", [(0.745, True), (0.71, False)])
def test_with_the_defaults_a_plate_joins_a_screen_whose_bottom_is_0_055_above_it(plate_top, joins):
    """stand_gap 0.08 (thirty-second round): the screen of GAP_* (z 0.80..1.20) and a foot plate
    0.03 tall under its middle. Its top 0.055 under the screen's bottom (z 0.715..0.745): within
    0.08, a foot (0.05 before: a "mouse"); 0.09 under (z 0.68..0.71): not."""
    a = defaults()["association"]
    boxes = make_boxes([GAP_CENTER[0], [2.22, 0.0, plate_top - 0.015]], [GAP_SIZE[0], [0.14, 0.24, 0.03]])
    got = stand_pairs(boxes, np.array([TV, MOUSE]), a["stand_gap"], a["stand_margin"], low=a["stand_low"],
                      centred=a["stand_centred"], within=a["stand_within"])
    assert [(i, j) for _, i, j in got] == ([(0, 1)] if joins else [])


# A screen's box grown 0.37 m deep (tum-fr1-rpy, every third frame from frame 1 backwards, frame
# 158), all yaw 0: x -0.31..0.31 (its length), y -0.185..0.185, z 0.7325..1.2675. Under it, its
# top 0.0545 below the screen box's bottom, things 0.13 x 0.115 x 0.074 m: the white mouse in its
# corner, centre (0.30, 0.17): 0.30 of the 0.62 length along (under half: 0.31), 0.17 across
# (under half the 0.37 depth: 0.185); and a foot under its middle, centre (0.05, 0.17).
CORNER_SCREEN = ([0.0, 0.0, 1.0], [0.62, 0.37, 0.535])


@pytest.mark.parametrize("x, centred, pair", [
    (0.30, 0.25, False),   # along, 0.30 is over stand_centred 0.25 x 0.62 = 0.155: not a foot
    (0.30, None, True),    # stand_within alone (0.5 on both sides), as before the thirty-third round
    (0.05, 0.25, True),    # a foot under the screen's middle
])
def test_a_thing_under_the_corner_of_a_deep_screen_box_is_not_its_foot(x, centred, pair):
    b = Boxes(np.array([CORNER_SCREEN[0], [x, 0.17, 0.75]]), np.zeros(2),
              np.array([CORNER_SCREEN[1], [0.13, 0.115, 0.074]]), np.ones((2, 8), bool))
    out = stand_pairs(b, np.array([TV, MOUSE]), 0.08, 0.1, low=0.3, centred=centred, within=0.5)
    assert [(a, c) for _, a, c in out] == ([(0, 1)] if pair else [])
    if pair:
        assert out[0][0] == pytest.approx(0.0545)

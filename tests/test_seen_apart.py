"""association.seen_apart_gap / seen_apart_share (issue 9, thirty-third round): a detection beside a
map object that the frame's depth shows standing in its own box is another thing, and so are two map
objects apart that the depth shows both standing in their boxes. On tum-fr1-rpy the game controller,
5 cm beside the red trackball and also called "mouse", took the trackball's object by eq. 2.

The scene (tests/scene.py: camera at (0, 0, 1) looking along +x) holds a trackball, a 0.06 x 0.09 x
0.06 m block at x 0.97..1.03, y -0.045..0.045, z 0.97..1.03, in front of a wall at x = 4; its map box
is 0.07 x 0.10 x 0.07 m around it. The controller's detection box is 0.09 x 0.19 x 0.10 m beside it
at the same height, seen from the trackball's side only (its four vertices at its lower y)."""

import numpy as np
import pytest

from ltc_cli import plugins
from ltc_cli.config import load_config
from ltc_cli.geometry.boxes import Boxes
from ltc_cli.map.model import ACTIVE, MERGED, SemanticMap
from ltc_cli.pipeline.association import footprint_gaps, seen_elsewhere
from ltc_cli.pipeline.maintenance import standing_in_box
from ltc_cli.pipeline.mapper import Mapper
from tests.scene import INTR, T_world_camera, render

CLASSES = ["mouse", "book"]  # then other
MOUSE = np.array([0.9, 0.05, 0.05])
TRACKBALL = ([1.0, 0.0, 1.0], [0.07, 0.10, 0.07])
THING = (0.97, 1.03, -0.045, 0.045, 0.97, 1.03)


def one(center, size, visible=None) -> Boxes:
    vis = np.ones((1, 8), bool) if visible is None else np.asarray(visible, bool)[None]
    return Boxes(np.array([center], float), np.zeros(1), np.array([size], float), vis)


def controller(gap: float) -> Boxes:
    """The controller's box ``gap`` metres beyond the trackball box's side at y = 0.05."""
    center = [1.0, 0.05 + gap + 0.095, 1.0]
    near = one(center, [0.09, 0.19, 0.10]).corners[0][:, 1] < center[1]  # vertices 0, 1, 4, 5
    return one(center, [0.09, 0.19, 0.10], near)


def depth(with_trackball: bool = True) -> np.ndarray:
    return render([THING] if with_trackball else [])[0]


def test_seen_elsewhere_by_hand():
    gaps, standing = np.array([0.02, 0.05, 0.05, np.inf]), np.array([True, True, False, True])
    assert seen_elsewhere(gaps, standing, 0.03).tolist() == [False, True, False, True]
    assert seen_elsewhere(gaps, standing, 0.06).tolist() == [False, False, False, True]  # inf: no common height
    assert seen_elsewhere(gaps, standing, None).tolist() == [False] * 4  # the paper


def test_the_controller_lies_apart_within_eq2():
    """Eq. 2 over the four vertices visible in both, best at the half turn: each of the controller's
    near corners, e.g. (0.955, 0.10, 0.95), against the trackball box's opposite one (1.035, 0.05,
    0.965): sqrt(0.08^2 + 0.05^2 + 0.015^2) = 0.0955 m, under the same-class threshold min(0.4, 1.5 x
    the controller's half diagonal sqrt(0.09^2 + 0.19^2 + 0.1^2) / 2 = 0.1164) = 0.1745 m; the
    footprints 0.05 m apart (0.02 for the nearer one: 0.0838 m by eq. 2)."""
    cfg = load_config(None, [])
    d = plugins.get("metrics", "vertex").factory(cfg["association"]).distance
    assert d(controller(0.05), one(*TRACKBALL))[0] == pytest.approx(np.sqrt(0.08**2 + 0.05**2 + 0.015**2))
    assert d(controller(0.02), one(*TRACKBALL))[0] == pytest.approx(np.sqrt(0.08**2 + 0.02**2 + 0.015**2))
    assert footprint_gaps(controller(0.05), one(*TRACKBALL))[0] == pytest.approx(0.05)


def test_standing_in_box_by_the_depth():
    """The block's front face at x = 0.97 lies in the box (x 0.965..1.035); of the box's image, the
    rays above the raised bottom (z 0.965 + occupied_lift 0.03 = 0.995) that meet the block end in
    it: about 0.09 / 0.10 of its width times 0.035 / 0.07 of its height, 0.45 of its visible pixels
    (0.5 on the 8-pixel ray grid), over seen_apart_share 0.3 and under 0.6. Without the block the
    rays end on the wall 3 m behind: none."""
    m_cfg = load_config(None, [])["maintenance"]
    box, T = one(*TRACKBALL), T_world_camera()
    assert standing_in_box(box, T, depth(True), INTR, (0.3, 6.0), m_cfg, 0.3).tolist() == [True]
    assert standing_in_box(box, T, depth(True), INTR, (0.3, 6.0), m_cfg, 0.6).tolist() == [False]
    assert standing_in_box(box, T, depth(False), INTR, (0.3, 6.0), m_cfg, 0.3).tolist() == [False]
    # Hidden behind something 0.5 m from the camera: no visible pixel, nothing to say.
    near = np.full((INTR.height, INTR.width), 0.5, np.float32)
    assert standing_in_box(box, T, near, INTR, (0.3, 6.0), m_cfg, 0.3).tolist() == [False]


def mapper_after_frame(overrides, frame_depth, objects):
    """A mapper (static policy) over a map of Defined "mouse" objects (center, size, n_det, vertices
    visible) after one
    frame with no detections and ``frame_depth``: its depth is the one association and merges read.
    ``association.max_union_length`` is off: it would part the trackball and the controller by
    their length alone, and these tests ask what the depth decides."""
    cfg = load_config(None, ["association.max_union_length={}", *overrides])
    smap = SemanticMap.new(CLASSES)
    for center, size, n_det, visible in objects:
        smap.objects.append(center=np.array(center, float), yaw=0.0, size=np.array(size, float),
                            visible=np.asarray(visible, bool), defined=True, scores=MOUSE.copy(), n_det=n_det,
                            status=ACTIVE, first_session=0, last_session=0)
    mapper = Mapper(smap, cfg, plugins.get("metrics", "vertex").factory(cfg["association"]),
                    plugins.get("policies", "static").factory(cfg["maintenance"]), session=0)
    res = mapper.process_frame(0, "0", [], [], frame_depth, T_world_camera(), INTR, (0.3, 6.0))
    return mapper, res


@pytest.mark.parametrize("overrides, gap, trackball_there, takes_it", [
    ((), 0.05, True, False),                                   # the trackball seen in its box: two things
    (("association.seen_apart_gap=null",), 0.05, True, True),  # the paper: eq. 2 alone
    ((), 0.05, False, True),   # its box seen through (a localiser's drift put it beside its thing)
    ((), 0.02, True, True),    # within the gap: one thing
])
def test_a_detection_beside_a_thing_seen_in_its_place(overrides, gap, trackball_there, takes_it):
    # defined_min_overlap is off: the whole detection shares no ground with the whole trackball's
    # box, and this test is of seen_apart alone.
    overrides = (*overrides, "association.defined_min_overlap=null")
    mapper, _ = mapper_after_frame(overrides, depth(trackball_there), [(*TRACKBALL, 2, [True] * 8)])
    row, _ = mapper._associate(controller(gap), 0, np.array([0]), True)
    assert (row == 0) == takes_it


CONTROLLER = ([1.0, 0.195, 1.0], [0.09, 0.19, 0.10], 2, controller(0.05).visible[0])
CONTROLLER_THING = (0.96, 1.04, 0.105, 0.285, 0.955, 1.045)


@pytest.mark.parametrize("overrides, things, merged", [
    ((), [THING, CONTROLLER_THING], False),                         # both seen in their boxes
    (("association.seen_apart_gap=null",), [THING, CONTROLLER_THING], True),
    ((), [CONTROLLER_THING], True),                                 # the trackball's box seen through
])
def test_two_objects_seen_in_their_places_do_not_merge(overrides, things, merged):
    """The trackball's object and the controller's (made from the detection above): eq. 2 over the
    four vertices visible in both is 0.0955 m as above, and both are Defined, so neither
    merge_min_overlap nor (set off here: this test is of seen_apart alone) defined_apart_detections
    keeps them apart; the depth does, when it shows both in their boxes."""
    overrides = (*overrides, "association.defined_apart_detections=null")
    objects = [(*TRACKBALL, 2, [True] * 8), CONTROLLER]
    mapper, res = mapper_after_frame(overrides, render(things)[0], objects)
    assert res.merged == int(merged)
    assert list(mapper.map.objects.status[:2]) == ([ACTIVE, MERGED] if merged else [ACTIVE, ACTIVE])


@pytest.mark.parametrize("overrides, trackball_there, adjoins", [
    ((), True, False),
    (("association.seen_apart_gap=null",), True, True),
    ((), False, True),
])
def test_a_small_partial_view_adjoins_no_thing_seen_in_its_place(overrides, trackball_there, adjoins):
    """Both partial, the controller's box wholly seen 0.04 m beside the trackball's: eq. 2 over all 8
    vertices, best unturned, is the mean of sqrt(0.01^2 + 0.14^2 + 0.015^2) = 0.1412 (its four
    vertices at y 0.09) and sqrt(0.01^2 + 0.23^2 + 0.015^2) = 0.2307 (at y 0.28), 0.1859 m: over
    the 0.1745 m cap. The gap is within partial_adjoin_gap 0.05, so the paper's adjoining of partial
    views takes it (int8 at frame 89 of tum-fr1-rpy: 4.8 cm); not where the depth shows the
    trackball in its box. Both footprints are small (0.19 m, under occupied_max_width 0.25)."""
    d = plugins.get("metrics", "vertex").factory(load_config(None, [])["association"]).distance
    det = one([1.0, 0.05 + 0.04 + 0.095, 1.0], [0.09, 0.19, 0.10])
    assert d(det, one(*TRACKBALL))[0] == pytest.approx((np.sqrt(0.019925) + np.sqrt(0.053225)) / 2)
    mapper, _ = mapper_after_frame(overrides, depth(trackball_there), [(*TRACKBALL, 2, [True] * 8)])
    mapper.map.objects.cols["defined"][0] = False
    row, adjoined = mapper._associate(det, 0, np.array([0]), False)
    assert (row == 0) == adjoins
    assert adjoined == adjoins

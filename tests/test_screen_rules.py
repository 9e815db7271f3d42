"""modeling.wider_than and modeling.max_depth_ratio (issue 9, twelfth round, from tum-fr1-rpy):
a "laptop" wider than any laptop is a monitor (COCO's tv), and a "tv" box far deeper than any
screen is a mask spilled over what lies in front of it. Expected values are worked out by hand from
the rendered scenes (tests/scene.py: camera at the origin looking along +x, z up, f 500,
depth = x)."""

import numpy as np
import pytest

from ltc_cli.config import defaults
from ltc_cli.map.model import top_class
from ltc_cli.pipeline.frame_modeling import ClassFlags, model_frame
from tests.scene import INTR, T_world_camera, render
from tests.test_monitor_rules import CLASSES, LAPTOP, TV, vector


def stage_1(boxes, score_vector, cfg):
    """Stage 1 of one frame with one detection whose mask is every rendered box's pixels."""
    depth, masks = render(boxes, wall_x=4.0)
    mask = np.logical_or.reduce(masks)
    return model_frame([mask], [score_vector], depth, T_world_camera(), INTR, (0.3, 6.0), cfg,
                       ClassFlags.from_settings(CLASSES, cfg))


@pytest.mark.parametrize("half_width, expected", [(0.28, "tv"), (0.18, "laptop")])
def test_stage_1_calls_a_laptop_wider_than_any_laptop_a_tv(half_width, expected):
    """A face 2 m ahead, 0.2 m tall (under the 0.35 m height bound), detected as laptop 0.6: 0.56 m
    wide it is over the 0.45 m width bound and comes out tv; 0.36 m wide it stays a laptop. Without
    the rule both stay laptops."""
    cfg = defaults()
    cfg["modeling"]["wider_than"] = {"laptop": {"width": 0.45, "is": "tv"}}
    face = [(2.0, 2.05, -half_width, half_width, 0.9, 1.1)]
    out = stage_1(face, vector(LAPTOP, 0.6), cfg)
    assert len(out.modeled.source) == 1
    assert out.modeled.boxes.size[0, :2].max() == pytest.approx(2 * half_width, abs=0.03)
    assert CLASSES[int(top_class(out.scores[0]))] == expected
    cfg["modeling"]["wider_than"] = {}
    assert CLASSES[int(top_class(stage_1(face, vector(LAPTOP, 0.6), cfg).scores[0]))] == "laptop"


def staircase(steps: int):
    """Faces 1 m wide every 0.1 m from x = 2.0 on, from the floor up to 0.5, 0.55, ... m, all under
    the camera's height (z 1.0): each shows its top above the one before it, so the image is one
    region with depth readings 2.0 ... 2.0 + 0.1 (steps - 1) m, each step about 0.1 m from the next
    (under DBSCAN's eps 0.15): one cluster as deep as the stairs."""
    return [(2.0 + 0.1 * k, 2.05 + 0.1 * k, -0.5, 0.5, 0.0, 0.5 + 0.05 * k) for k in range(steps)]


@pytest.mark.parametrize("steps, ratio, boxes", [
    (9, None, 1),   # the paper: a 0.85 m deep "tv" box
    (9, 6.0, 0),    # over 6 x tv's 0.1 m class depth: no box
    (4, 6.0, 1),    # 0.35 m deep (a screen on its foot, seen at an angle): kept
])
def test_a_tv_box_deeper_than_any_screen_gives_no_box(steps, ratio, boxes):
    cfg = defaults()
    cfg["modeling"]["max_depth_ratio"] = ratio
    assert cfg["modeling"]["class_depth"]["tv"] == 0.1
    out = stage_1(staircase(steps), vector(TV, 0.8), cfg)
    assert len(out.modeled.source) == boxes
    if boxes:
        # The stairs' depth along x: from the first face to the last one's back, 0.1 (steps - 1)
        # + 0.05 m, less the few cm thinning takes off the far edge.
        assert out.modeled.boxes.size[0, :2].min() == pytest.approx(0.1 * (steps - 1) + 0.05, abs=0.06)


# modeling.narrower_than (issue 9, fourteenth round): a whole "couch" under 1 m is no couch.
SEATS = ["couch", "chair", "bed"]  # then other


def couch_vector():
    return np.array([0.6, 0.3, 0.05, 0.05])  # couch 0.6, chair second


def test_relabel_too_narrow_by_hand():
    """couch 0.6, chair 0.3: a Defined 0.8 m box moves the 0.6 to chair (0.9); a Defined 1.4 m box,
    a partial 0.8 m box, and a Defined 0.8 m box with no second class stay couches."""
    from ltc_cli.pipeline.frame_modeling import NEXT, relabel_too_narrow

    min_width = np.array([1.0, 0.0, 0.0, 0.0])
    to = np.array([NEXT, -1, -1, -1])
    alone = np.array([1.0, 0.0, 0.0, 0.0])
    scores = [couch_vector(), couch_vector(), couch_vector(), alone]
    out = relabel_too_narrow(scores, np.arange(4), np.array([0.8, 1.4, 0.8, 0.8]),
                             np.array([True, True, False, True]), min_width, to)
    assert out[0] == pytest.approx([0.0, 0.9, 0.05, 0.05])
    for k in (1, 2, 3):
        assert out[k] == pytest.approx(scores[k])


def test_narrower_than_bounds_from_settings():
    from ltc_cli.pipeline.frame_modeling import NEXT

    cfg = defaults()
    assert cfg["modeling"]["narrower_than"] == {"couch": {"width": 1.0, "is": "next"}}
    flags = ClassFlags.from_settings(SEATS, cfg)
    assert flags.min_width.tolist() == [1.0, 0.0, 0.0, 0.0] and flags.narrower_is.tolist() == [NEXT, -1, -1, -1]
    flags = ClassFlags.from_settings(["chair", "bed"], cfg)  # no couch in the map: nothing to judge
    assert flags.min_width.tolist() == [0.0, 0.0, 0.0]


@pytest.mark.parametrize("half_width, rule, expected", [
    (0.4, True, "chair"),    # a whole 0.8 m "couch": the detector's next class
    (0.7, True, "couch"),    # 1.4 m: a couch
    (0.4, False, "couch"),   # narrower_than {}: the paper
])
def test_stage_1_calls_a_whole_couch_under_one_metre_its_next_class(half_width, rule, expected):
    """A 0.3 m deep block 2 m ahead, z 0.2-0.8 m, under the camera (z 1.0), fully in view: with no
    floor or class-depth rule and the far side taken as observed (thin_extent 0.01) all 8 corners
    are visible and the box is Defined, as wide as the block."""
    cfg = defaults()
    cfg["modeling"].update(floor_classes=[], class_depth={}, thin_extent=0.01)
    if not rule:
        cfg["modeling"]["narrower_than"] = {}
    depth, masks = render([(2.0, 2.3, -half_width, half_width, 0.2, 0.8)], wall_x=4.0)
    out = model_frame(masks, [couch_vector()], depth, T_world_camera(), INTR, (0.3, 6.0), cfg,
                      ClassFlags.from_settings(SEATS, cfg))
    assert out.modeled.defined.tolist() == [True]
    assert out.modeled.boxes.size[0, :2].max() == pytest.approx(2 * half_width, abs=0.03)
    assert SEATS[int(top_class(out.scores[0]))] == expected


# modeling.defined_min_width (issue 9, fourteenth round): no whole bed is 1.5 m long.
def test_not_whole_by_hand():
    from ltc_cli.pipeline.frame_modeling import not_whole

    # Defined 1.1 m under a 1.5 m bound: partial; 1.9 m: stays Defined; a partial box stays partial;
    # a class with no bound (0) stays Defined however small.
    out = not_whole(np.array([True, True, False, True]), np.array([1.1, 1.9, 1.1, 0.3]),
                    np.array([1.5, 1.5, 1.5, 0.0]))
    assert out.tolist() == [False, True, False, True]


@pytest.mark.parametrize("half_width, bound, defined", [
    (0.4, {"bed": 1.5}, False),   # a whole-looking 0.8 m "bed": a part of one
    (0.8, {"bed": 1.5}, True),    # 1.6 m: whole
    (0.4, {}, True),              # {}: the paper (every corner visible, so Defined)
])
def test_stage_1_never_calls_a_bed_box_shorter_than_any_bed_whole(half_width, bound, defined):
    """The fully visible block of the couch test above, detected as bed 0.9 (no rule moves its
    class): Defined by its corners, and not whole by its size."""
    cfg = defaults()
    cfg["modeling"].update(floor_classes=[], class_depth={}, thin_extent=0.01, defined_min_width=bound)
    depth, masks = render([(2.0, 2.3, -half_width, half_width, 0.2, 0.8)], wall_x=4.0)
    out = model_frame(masks, [np.array([0.05, 0.05, 0.9, 0.0])], depth, T_world_camera(), INTR, (0.3, 6.0), cfg,
                      ClassFlags.from_settings(SEATS, cfg))
    assert out.modeled.boxes.visible.all()
    assert out.modeled.boxes.size[0, :2].max() == pytest.approx(2 * half_width, abs=0.03)
    assert out.modeled.defined.tolist() == [defined]
    assert SEATS[int(top_class(out.scores[0]))] == "bed"


@pytest.mark.parametrize("half_width, defined", [
    (0.35, False),  # a whole-looking 0.7 m "dining table": an end of one (no table seats two under 0.8 m)
    (0.5, True),    # 1.0 m: whole
])
def test_default_never_calls_a_table_box_shorter_than_any_table_whole(half_width, defined):
    """With the default settings, a fully visible block detected as dining table 0.9 is Defined by
    its corners only when it is at least 0.8 m long (modeling.defined_min_width)."""
    classes = ["dining table", "chair"]
    cfg = defaults()
    assert cfg["modeling"]["defined_min_width"]["dining table"] == 0.8
    cfg["modeling"].update(floor_classes=[], class_depth={}, thin_extent=0.01)
    depth, masks = render([(2.0, 2.3, -half_width, half_width, 0.2, 0.8)], wall_x=4.0)
    out = model_frame(masks, [np.array([0.9, 0.05, 0.05])], depth, T_world_camera(), INTR, (0.3, 6.0), cfg,
                      ClassFlags.from_settings(classes, cfg))
    assert out.modeled.boxes.visible.all()
    assert out.modeled.boxes.size[0, :2].max() == pytest.approx(2 * half_width, abs=0.03)
    assert out.modeled.defined.tolist() == [defined]


def test_deepest_sides_by_hand():
    """modeling.max_short_side (issue 9, twenty-ninth round) with max_depth_ratio: class depths 0.1
    (a tv), none, 0.2 (a book); ratio 6 gives 0.6, no bound, 1.2; the per-class bounds inf, 0.5,
    0.6 cap them at 0.6, 0.5, 0.6."""
    from ltc_cli.pipeline.frame_modeling import deepest_sides

    prior = np.array([0.1, np.nan, 0.2])
    np.testing.assert_allclose(deepest_sides(prior, 6.0, None), [0.6, np.inf, 1.2])
    np.testing.assert_allclose(deepest_sides(prior, 6.0, np.array([np.inf, 0.5, 0.6])), [0.6, 0.5, 0.6])
    np.testing.assert_allclose(deepest_sides(prior, None, np.array([np.inf, 0.5, 0.6])), [np.inf, 0.5, 0.6])


@pytest.mark.parametrize("steps, bound, boxes", [
    (6, None, 1),   # no per-class bound (and no ratio): the 0.5 m deep box stays
    (6, 0.3, 0),    # 0.5 m deep, over 0.3: no box
    (2, 0.3, 1),    # 0.1 m deep: kept
])
def test_a_box_deeper_than_its_class_ever_is_gives_no_box(steps, bound, boxes):
    """The staircase of the test above, detected as tv, max_depth_ratio off: the shorter side of its
    box runs from the first face's front to the last one's, 0.1 (steps - 1) m (0.5 and 0.1; the
    last face's back is hidden behind its own front)."""
    cfg = defaults()
    cfg["modeling"]["max_depth_ratio"] = None
    cfg["modeling"]["max_short_side"] = {} if bound is None else {"tv": bound}
    out = stage_1(staircase(steps), vector(TV, 0.8), cfg)
    assert len(out.modeled.source) == boxes
    if boxes:
        assert out.modeled.boxes.size[0, :2].min() == pytest.approx(0.1 * (steps - 1), abs=0.03)

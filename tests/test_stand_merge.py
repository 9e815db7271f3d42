"""A monitor's foot called "mouse" is the monitor's lower part (association stand_gap / stand_margin),
and a partial box does not merge with the neighbour its visible corners touch (merge_min_overlap);
issue 9, eleventh round, tum-fr1-rpy. Expected values are worked out by hand."""

import numpy as np
import pytest

from ltc_cli import plugins
from ltc_cli.config import defaults
from ltc_cli.geometry.boxes import Boxes
from ltc_cli.map.model import ACTIVE, MERGED, SemanticMap
from ltc_cli.pipeline.deduplication import duplicate_pairs
from ltc_cli.pipeline.stands import centred_under, stand_pairs
from ltc_cli.pipeline.integration import confirmed_side
from ltc_cli.pipeline.mapper import Mapper
from tests.scene import INTR, T_world_camera
from tests.test_identity import CLASSES

TV, MOUSE, CUP, TABLE = 1, 2, 3, 4

# All axis-aligned (yaw 0); footprints x range, y range; z range:
# 0 tv     x 2.15..2.25  y -0.27..0.27  z 1.025..1.375   (a screen 0.54 wide, 0.1 deep, 0.35 tall)
# 1 mouse  x 2.13..2.27  y -0.12..0.12  z 0.965..1.005   under 0: its top 0.02 below 0's bottom; its
#          footprint 0.14 x 0.24, of which 0.10 x 0.24 under 0 and all under 0 grown by 0.05 per side
# 2 cup    x 2.15..2.25  y  0.60..0.70  z 0.965..1.005   as 1 but beside 0: 0.33 from 0's footprint
# 3 cup    x 2.10..2.20  y -0.05..0.05  z 0.80..0.90     under 1 and 0, 0.065 and 0.125 below their bottoms
# 4 table  x 1.60..2.80  y -0.50..0.50  z 0.00..0.75     under all of them, larger than 0
# 5 cup    x 2.15..2.25  y -0.05..0.05  z 0.75..0.87     on the table (4): above it, smaller
CENTER = [[2.2, 0, 1.2], [2.2, 0, 0.985], [2.2, 0.65, 0.985], [2.15, 0, 0.85], [2.2, 0, 0.375], [2.2, 0, 0.81]]
SIZE = [[0.1, 0.54, 0.35], [0.14, 0.24, 0.04], [0.1, 0.1, 0.04], [0.1, 0.1, 0.10], [1.2, 1.0, 0.75],
        [0.1, 0.1, 0.12]]
TOP = np.array([TV, MOUSE, CUP, CUP, TABLE, CUP])


def class_vector(cls: int) -> np.ndarray:
    """0.9 on ``cls``, the rest spread over the other classes, nothing on ``other``."""
    v = np.full(len(CLASSES) + 1, 0.1 / (len(CLASSES) - 1))
    v[cls], v[-1] = 0.9, 0.0
    return v


def empty_frame(smap, cfg, session: int):
    """A mapper over ``smap`` (vertex metric, static policy: no non-detections) after one frame with no
    detections in which the scene's objects are in view: (mapper, the frame's result)."""
    mapper = Mapper(smap, cfg, plugins.get("metrics", "vertex").factory(cfg["association"]),
                    plugins.get("policies", "static").factory(cfg["maintenance"]), session=session)
    depth = np.full((INTR.height, INTR.width), 4.0, np.float32)
    return mapper, mapper.process_frame(0, "0", [], [], depth, T_world_camera(), INTR, (0.3, 6.0))


def boxes(rows=None) -> Boxes:
    rows = list(range(len(CENTER))) if rows is None else rows
    return Boxes(np.array(CENTER, float)[rows], np.zeros(len(rows)), np.array(SIZE, float)[rows],
                 np.ones((len(rows), 8), bool))


def test_stand_pairs_by_hand():
    pairs = stand_pairs(boxes(), TOP, 0.05, 0.05)
    # Only the foot under the screen: 2 is beside it, 3 too far below both, 5 stands on the table
    # (above it), and 3 and 5 are not under the table either: their bottoms are above its bottom.
    assert [(a, b) for _, a, b in pairs] == [(0, 1)]
    assert pairs[0][0] == pytest.approx(0.02)
    # Without the margin 0.10 of the foot's 0.14 lie under the screen: 0.71 >= 0.5, still a pair;
    # asking for 0.75 of it, none.
    assert [(a, b) for _, a, b in stand_pairs(boxes(), TOP, 0.05, 0.0)] == [(0, 1)]
    assert stand_pairs(boxes(), TOP, 0.05, 0.0, min_cover=0.75) == []
    # A gap of 0.11 m takes the cups 0.065 (3) and 0.095 (5) under the foot too, not 3 at 0.125
    # under the screen (5 sits on the table, 0.155 under the screen).
    assert sorted((a, b) for _, a, b in stand_pairs(boxes(), TOP, 0.11, 0.05)) == [(0, 1), (1, 3), (1, 5)]
    # One class for both: the same object's parts are for eq. 2 and containment, not this rule.
    assert stand_pairs(boxes([0, 1]), np.array([TV, TV]), 0.05, 0.05) == []
    assert stand_pairs(boxes(), TOP, None, 0.05) == []


def test_a_stand_is_low_a_mug_by_the_screen_is_not_its_foot():
    """association.stand_low (issue 9, twenty-first round): on the level tum-fr1-rpy map the mug in
    front of one end of a monitor, 0.13-0.17 m tall, had its top within 5 cm of the screen's bottom
    and went into it; the monitors' feet are flat (0.05-0.12 m under 0.37 m screens).
    Here the screen (0) is 0.35 tall and the foot (1) 0.04: 0.114 of it. A mug (6) 0.17 tall stands
    under the screen's end: x 2.15..2.25, y 0.20..0.30, z 0.845..1.015, its top 0.01 under the
    screen's bottom, its footprint wholly under the screen grown by 0.05: 0.486 of its height."""
    center = CENTER[:2] + [[2.2, 0.25, 0.93]]
    size = SIZE[:2] + [[0.1, 0.1, 0.17]]
    top = np.array([TV, MOUSE, CUP])
    b = Boxes(np.array(center, float), np.zeros(3), np.array(size, float), np.ones((3, 8), bool))
    assert sorted((a, c) for _, a, c in stand_pairs(b, top, 0.05, 0.05)) == [(0, 1), (0, 2)]
    assert [(a, c) for _, a, c in stand_pairs(b, top, 0.05, 0.05, low=0.3)] == [(0, 1)]
    assert [(a, c) for _, a, c in stand_pairs(b, top, 0.05, 0.05, low=0.12)] == [(0, 1)]
    assert stand_pairs(b, top, 0.05, 0.05, low=0.11) == []  # 0.04 / 0.35 = 0.114 > 0.11
    assert sorted((a, c) for _, a, c in stand_pairs(b, top, 0.05, 0.05, low=0.49)) == [(0, 1), (0, 2)]


def test_a_partial_box_does_not_merge_with_the_neighbour_its_corners_touch():
    """Two monitors edge to edge: eq. 2 over the vertices visible in both can be small (here a
    distance of 0 stands for it) while their footprints share 0.02 x 0.1 = 0.002 m², 0.04 of
    either's 0.05 m²."""
    pair = Boxes(np.array([[0.0, 0, 1], [0.48, 0, 1]]), np.zeros(2), np.array([[0.5, 0.1, 0.4]] * 2),
                 np.ones((2, 8), bool))
    top = np.array([TV, TV])

    def zero(one, many):
        return np.zeros(len(many))

    def merged(min_overlap, defined):
        return [(a, b) for _, a, b in duplicate_pairs(pair, top, zero, 0.4, 0.25, None, None,
                                                      min_overlap=min_overlap, defined=np.array(defined))]

    assert merged(None, [False, True]) == [(0, 1)]       # the paper: the distance alone
    assert merged(0.2, [False, True]) == []               # one partial: 0.04 < 0.2 of the footprint
    assert merged(0.2, [True, True]) == [(0, 1)]          # both Defined: all 8 vertices were compared
    assert merged(0.03, [False, False]) == [(0, 1)]       # 0.04 >= 0.03


def test_two_defined_boxes_of_earlier_sessions_keep_the_overlap_test():
    """established_apart: the same two monitors, both Defined. Made in an earlier session, both of
    them, they need the 0.2 of the footprint too (0.04 < 0.2: apart); one of them made in this
    session, the Defined exemption stands (all 8 vertices compared: they merge)."""
    def merged(established, x=0.48):
        pair = Boxes(np.array([[0.0, 0, 1], [x, 0, 1]]), np.zeros(2), np.array([[0.5, 0.1, 0.4]] * 2),
                     np.ones((2, 8), bool))
        return [(a, b) for _, a, b in duplicate_pairs(
            pair, np.array([TV, TV]), lambda one, many: np.zeros(len(many)), 0.4, 0.25, None, None,
            min_overlap=0.2, defined=np.array([True, True]), established=np.array(established))]

    assert merged([True, True]) == []
    assert merged([True, False]) == [(0, 1)]
    assert merged([False, False]) == [(0, 1)]
    # Sharing half of the footprint (0.25 apart: 0.25 x 0.1 of 0.05 m²), they merge whatever their age.
    assert merged([True, True], x=0.25) == [(0, 1)]


def test_two_defined_boxes_of_different_labels_keep_the_overlap_test():
    """labels_apart: a whole cup (0.1 x 0.1 m footprint) and a whole mouse beside it whose eq. 2
    distance is under the threshold (0 stands for it). Footprints 0.2 m apart share nothing: with
    labels_apart they stay two, without it the Defined exemption merges them; with the cup half
    on the mouse's footprint (0.05 x 0.1 of the cup's 0.01 m^2: 0.5 >= 0.2) they merge either way.
    A cup and a cup (one label) keep the exemption."""
    def merged(labels_apart, y=0.2, top=(CUP, MOUSE)):
        pair = Boxes(np.array([[2.2, 0.0, 0.8], [2.2, y, 0.8]]), np.zeros(2),
                     np.array([[0.1, 0.1, 0.12], [0.1, 0.2, 0.04]]), np.ones((2, 8), bool))
        return [(a, b) for _, a, b in duplicate_pairs(
            pair, np.array(top), lambda one, many: np.zeros(len(many)), 0.4, 0.25, None, None,
            min_overlap=0.2, defined=np.array([True, True]), labels_apart=labels_apart)]

    assert merged(True) == []
    assert merged(False) == [(0, 1)]
    assert merged(True, y=0.1) == [(0, 1)]
    assert merged(True, top=(CUP, CUP)) == [(0, 1)]


def test_an_object_of_an_earlier_session_is_never_a_part():
    """stand_pairs with established flags: the foot (1) under the screen (0) is its part when the
    foot was made in this session, whatever the screen's age; made in an earlier one, it is not."""
    rows = [0, 1]
    for established, expected in (([False, False], [(0, 1)]), ([True, False], [(0, 1)]),
                                  ([False, True], []), ([True, True], [])):
        pairs = stand_pairs(boxes(rows), TOP[rows], 0.05, 0.05, established=np.array(established))
        assert [(a, b) for _, a, b in pairs] == expected, established


@pytest.mark.parametrize("apart", [False, True])
def test_on_a_revisit_two_established_monitors_stay_two(apart):
    """Through the mapper, session 1 (a revisit), no detections, static policy: two Defined tvs
    made in session 0, 0.48 m apart, their footprints sharing 0.02 x 0.1 m (0.04 of either), and
    eq. 2 over their 8 vertices 0.48 (under a same-class threshold of 0.5 set for this test). With
    established_apart they stay two; without it the older one absorbs the other."""
    cfg = defaults()
    cfg["association"]["threshold_same_class"] = 0.5
    cfg["association"]["established_apart"] = apart
    cfg["association"]["defined_apart_detections"] = None  # this test is of established_apart alone
    smap = SemanticMap.new(CLASSES)
    v = class_vector(TV)
    for y in (-0.24, 0.24):
        smap.objects.append(center=np.array([2.2, y, 1.2]), yaw=0.0, size=np.array([0.1, 0.5, 0.4]),
                            visible=np.ones(8, bool), defined=True, scores=v, n_det=30, status=ACTIVE,
                            first_session=0, last_session=0)
    mapper, res = empty_frame(smap, cfg, session=1)
    assert list(mapper.map.objects.status[:2]) == ([ACTIVE, ACTIVE] if apart else [ACTIVE, MERGED])
    assert res.merged == (0 if apart else 1)


@pytest.mark.parametrize("gap", [None, 0.05])
def test_the_foot_joins_the_screen_which_keeps_its_box_label_and_id(gap):
    """A map with the screen (0, detected 40 times) and its foot (1, "mouse", 60 times: more often
    than the screen, as on tum-fr1-rpy) in view of a frame with no detections (static policy: no
    non-detections): with the rule on, the foot is merged into the screen, whose box and class vector
    stay as they were (the foot's label names a part, so eq. 3 does not weigh it), and whose detection
    count is 100; with it off, both stay."""
    cfg = defaults()
    cfg["association"]["stand_gap"] = gap
    cfg["association"]["stand_margin"] = 0.05
    smap = SemanticMap.new(CLASSES)
    vectors = []
    for i, n_det in ((0, 40), (1, 60)):
        v = class_vector(TOP[i])
        vectors.append(v)
        smap.objects.append(center=np.array(CENTER[i], float), yaw=0.0, size=np.array(SIZE[i], float),
                            visible=np.ones(8, bool), defined=True, scores=v, n_det=n_det, status=ACTIVE)
    mapper, res = empty_frame(smap, cfg, session=0)
    t = mapper.map.objects
    if gap is None:
        assert res.merged == 0 and list(t.status[:2]) == [ACTIVE, ACTIVE]
        return
    assert res.merged == 1
    assert list(t.status[:2]) == [ACTIVE, MERGED]
    assert t.n_det[0] == 100
    np.testing.assert_allclose(t.center[0], CENTER[0])
    np.testing.assert_allclose(t.size[0], SIZE[0])
    np.testing.assert_allclose(t.scores[0], vectors[0])
    assert [(e.kind, e.object_id, e.other_id) for e in mapper.map.events if e.kind == "merged"] == [("merged", 1, 2)]


def test_confirmed_side_by_hand():
    # Another class and only one of the two tentative: the other one's box.
    assert confirmed_side(TV, TABLE, False, True) == "older"
    assert confirmed_side(TV, TABLE, True, False) == "newer"
    # One class (pieces of one object), or both tentative, or both confirmed: the merge's own box.
    assert confirmed_side(TV, TV, False, True) is None
    assert confirmed_side(TV, TABLE, True, True) is None
    assert confirmed_side(TV, TABLE, False, False) is None


@pytest.mark.parametrize("reshapes,table_det,session", [(True, 1, 1), (False, 1, 1), (False, 2, 1), (False, 1, 0)])
def test_a_tentative_object_of_another_class_does_not_reshape_a_confirmed_one(reshapes, table_det, session):
    """No detections, static policy. The map holds a partial tv made in session 0 (30 detections;
    x 2.0..2.4, y -0.25..0.25, z 0.6..1.4: 0.16 m³) and a partial "dining table" made in the
    current session (table_det detections; x 1.6..2.8, y -0.5..0.5, z 0.2..1.4: 1.44 m³). The tv
    lies wholly inside the table and their volume ratio, 0.16 / 1.44 = 0.11, is within
    other_class_volume_ratio (0.1), and each class vector gives the other's class 0.15 (at least
    merge_other_class_evidence, 0.1: one thing under two labels), so they merge by cross-class
    containment (0.7), and the older id (the tv) stays. With tentative_reshapes false its box stays exactly as it was while the table is
    tentative (one detection, under min_detections 2), in session 1 as in session 0; with it true,
    or with the table confirmed (two detections), the merge reshapes it."""
    cfg = defaults()
    cfg["association"]["tentative_reshapes"] = reshapes
    smap = SemanticMap.new(CLASSES)
    tv_box = (np.array([2.2, 0.0, 1.0]), np.array([0.4, 0.5, 0.8]))
    for cls, (center, size), n_det, first in ((TV, tv_box, 30, 0),
                                             (TABLE, (np.array([2.2, 0.0, 0.8]), np.array([1.2, 1.0, 1.2])), table_det, session)):
        v = np.full(len(CLASSES) + 1, 0.1 / (len(CLASSES) - 2))
        v[cls], v[TV + TABLE - cls], v[-1] = 0.75, 0.15, 0.0
        smap.objects.append(center=center, yaw=0.0, size=size, visible=np.zeros(8, bool), defined=False,
                            scores=v, n_det=n_det, status=ACTIVE, first_session=first, last_session=first)
    mapper = Mapper(smap, cfg, plugins.get("metrics", "vertex").factory(cfg["association"]),
                    plugins.get("policies", "static").factory(cfg["maintenance"]), session=session)
    depth = np.full((INTR.height, INTR.width), 4.0, np.float32)
    mapper.process_frame(0, "0", [], [], depth, T_world_camera(), INTR, (0.3, 6.0))
    t = mapper.map.objects
    assert list(t.status[:2]) == [ACTIVE, MERGED]
    assert int(np.argmax(t.scores[0][:-1])) == TV
    same = np.allclose(t.center[0], tv_box[0]) and np.allclose(t.size[0], tv_box[1])
    assert same == (not reshapes and table_det < cfg["maintenance"]["min_detections"])


def test_centred_under_is_judged_in_the_larger_boxs_own_frame():
    """centred_under by hand: box 1 at the origin, 0.5 long along its own x axis and 0.3 wide,
    turned 90 degrees (its length along world y). A centre 0.07 m along world y is 0.07 / 0.5 =
    0.14 of its length from its middle (within 0.15); 0.07 m along world x is 0.07 / 0.3 = 0.23 of
    its width (not within 0.15, within 0.25)."""
    def centred(xy, share):
        b = Boxes(np.array([[xy[0], xy[1], 0.05], [0.0, 0.0, 0.2]]), np.array([0.0, np.pi / 2]),
                  np.array([[0.05, 0.05, 0.1], [0.5, 0.3, 0.4]]), np.ones((2, 8), bool))
        return bool(centred_under(b, share)[0, 1])

    assert centred((0.0, 0.07), 0.15)
    assert not centred((0.07, 0.0), 0.15)
    assert centred((0.07, 0.0), 0.25)
    assert not centred((0.0, 0.08), 0.15)  # 0.16 of the length


# A screen whose box reaches the desk, with its foot inside it and a mug by its end (yaw 0):
# 0 tv    x 2.05..2.35  y -0.25..0.25  z 0.80..1.20  (0.3 deep, 0.5 long, 0.4 tall)
# 1 mouse x 2.11..2.31  y -0.05..0.09  z 0.78..0.94  the foot: 0.16 tall (0.4 of the screen, over
#         stand_low 0.3), its top 0.14 above the screen's bottom (over stand_gap 0.05) and in its
#         lower half (under 1.00), its bottom 0.02 below; its centre 0.01 / 0.3 = 0.033 of the
#         screen's depth and 0.02 / 0.5 = 0.04 of its length from the screen's centre
# 2 cup   x 2.10..2.30  y  0.12..0.26  z 0.78..0.94  the same box 0.19 along y: 0.38 of the length
FOOT_CENTER = [[2.2, 0.0, 1.0], [2.21, 0.02, 0.86], [2.2, 0.19, 0.86]]
FOOT_SIZE = [[0.3, 0.5, 0.4], [0.2, 0.14, 0.16], [0.2, 0.14, 0.16]]


def foot_boxes(center=FOOT_CENTER, size=FOOT_SIZE) -> Boxes:
    return Boxes(np.array(center, float), np.zeros(len(center)), np.array(size, float),
                 np.ones((len(center), 8), bool))


def test_a_foot_centred_under_its_screen_is_its_part_a_mug_by_its_end_is_not():
    """association.stand_centred (issue 9, twenty-ninth round), by hand on the boxes above."""
    top = np.array([TV, MOUSE, CUP])
    assert stand_pairs(foot_boxes(), top, 0.05, 0.1, low=0.3) == []
    pairs = stand_pairs(foot_boxes(), top, 0.05, 0.1, low=0.3, centred=0.25)
    assert [(a, b) for _, a, b in pairs] == [(0, 1)]
    assert pairs[0][0] == pytest.approx(0.14)  # |0.80 - 0.94|
    # The mug's centre is 0.38 of the length from the middle: within 0.4 it would be a foot too.
    assert sorted((a, b) for _, a, b in stand_pairs(foot_boxes(), top, 0.05, 0.1, low=0.3, centred=0.4)) \
        == [(0, 1), (0, 2)]
    # Over half the screen's height (0.22 > 0.20), or its top in the screen's upper half (the box
    # raised 0.07: top 1.01 > 1.00, bottom 0.85 no longer below the screen's 0.80 either): no foot.
    tall = [FOOT_SIZE[0], [0.2, 0.14, 0.22], FOOT_SIZE[2]]
    assert stand_pairs(foot_boxes(size=tall), top, 0.05, 0.1, low=0.3, centred=0.25) == []
    raised = [FOOT_CENTER[0], [2.21, 0.02, 0.93], FOOT_CENTER[2]]
    assert stand_pairs(foot_boxes(center=raised), top, 0.05, 0.1, low=0.3, centred=0.25) == []


@pytest.mark.parametrize("centred", [None, 0.25])
def test_through_the_mapper_the_centred_foot_joins_the_screen(centred):
    """The screen (0, 40 detections) and its centred foot (1, "mouse", 60) of the boxes above, in
    view of a frame with no detections (static policy): with stand_centred the foot merges into the
    screen, which keeps its box; without it (stand_low 0.3 and stand_gap 0.05 alone) both stay."""
    cfg = defaults()
    cfg["association"]["stand_centred"] = centred
    smap = SemanticMap.new(CLASSES)
    for i, (cls, n_det) in enumerate(((TV, 40), (MOUSE, 60))):
        v = class_vector(cls)
        smap.objects.append(center=np.array(FOOT_CENTER[i], float), yaw=0.0, size=np.array(FOOT_SIZE[i], float),
                            visible=np.ones(8, bool), defined=True, scores=v, n_det=n_det, status=ACTIVE)
    mapper, res = empty_frame(smap, cfg, session=0)
    t = mapper.map.objects
    assert list(t.status[:2]) == ([ACTIVE, ACTIVE] if centred is None else [ACTIVE, MERGED])
    assert res.merged == (0 if centred is None else 1)
    np.testing.assert_allclose(t.size[0], FOOT_SIZE[0])


def test_two_defined_boxes_each_well_seen_keep_the_overlap_test():
    """defined_apart_detections (issue 9, twenty-ninth round): the two monitors of the tests above
    (footprints sharing 0.04 of either, eq. 2 standing at 0), both Defined and made in this session.
    Each detected at least that often, they keep merge_min_overlap and stay two; one of them seen
    less, the Defined exemption stands and they merge; both well seen but sharing half their
    footprints (0.25 apart), they merge."""
    def merged(well_seen, x=0.48):
        pair = Boxes(np.array([[0.0, 0, 1], [x, 0, 1]]), np.zeros(2), np.array([[0.5, 0.1, 0.4]] * 2),
                     np.ones((2, 8), bool))
        return [(a, b) for _, a, b in duplicate_pairs(
            pair, np.array([TV, TV]), lambda one, many: np.zeros(len(many)), 0.4, 0.25, None, None,
            min_overlap=0.2, defined=np.array([True, True]), established=np.array([False, False]),
            well_seen=np.array(well_seen))]

    assert merged([True, True]) == []
    assert merged([True, False]) == [(0, 1)]
    assert merged([False, False]) == [(0, 1)]
    assert merged([True, True], x=0.25) == [(0, 1)]


@pytest.mark.parametrize("n_det, setting, apart", [((30, 12), 3, True), ((30, 3), 3, True), ((30, 2), 3, False),
                                                   ((30, 2), 1, True), ((30, 12), None, False)])
def test_through_the_mapper_two_well_seen_monitors_of_one_session_stay_two(n_det, setting, apart):
    """As the revisit test above, but both monitors made in this very session (0): with
    defined_apart_detections 3, detected 30 and 12 times, or 30 and 3 (both at least 3) they stay
    two, and 30 and 2 they do not; with 1 (the default since the thirty-eighth round) 30 and 2 stay
    two as well; with the setting off (None), the older absorbs the other (eq. 2 over 8 vertices 0.48
    under the 0.5 set here)."""
    cfg = defaults()
    cfg["association"]["threshold_same_class"] = 0.5
    cfg["association"]["defined_apart_detections"] = setting
    smap = SemanticMap.new(CLASSES)
    v = class_vector(TV)
    for y, n in zip((-0.24, 0.24), n_det):
        smap.objects.append(center=np.array([2.2, y, 1.2]), yaw=0.0, size=np.array([0.1, 0.5, 0.4]),
                            visible=np.ones(8, bool), defined=True, scores=v, n_det=n, status=ACTIVE,
                            first_session=0, last_session=0)
    mapper, res = empty_frame(smap, cfg, session=0)
    assert list(mapper.map.objects.status[:2]) == ([ACTIVE, ACTIVE] if apart else [ACTIVE, MERGED])
    assert res.merged == (0 if apart else 1)


@pytest.mark.parametrize("setting, apart", [(None, False), (3, False), (2, False), (1, True)])
def test_two_whole_piles_seen_once_and_twice_stay_two(setting, apart):
    """Two piles side by side on a desk, both called "book" (tum-fr1-rpy's desk end at half its
    frame rate, docs/decisions.md thirty-eighth round): whole 0.30 x 0.20 x 0.08 m boxes, Defined,
    made in this session, detected twice and once, their centres 0.25 m apart along their length.
    By hand: their footprints share 0.05 x 0.20 m, 1/6 of either (under merge_min_overlap 0.2); eq.
    2 over the 8 vertices is 0.25 (a shift), under the 0.4 of one class and under its cap, 1.5 times
    the half diagonal sqrt(0.30^2 + 0.20^2 + 0.08^2) / 2 = 0.185, i.e. 0.277. Exempt as two Defined
    boxes (defined_apart_detections None, or 3 or 2 with one pile seen once) they merge into a box
    between the two; with 1 they keep the overlap test and stay two."""
    cfg = defaults()
    cfg["association"]["defined_apart_detections"] = setting
    smap = SemanticMap.new(CLASSES)
    v = class_vector(CUP)  # the test's classes are generic: one class for both piles
    for x, n in zip((2.075, 2.325), (2, 1)):
        smap.objects.append(center=np.array([x, 0.0, 0.79]), yaw=0.0, size=np.array([0.30, 0.20, 0.08]),
                            visible=np.ones(8, bool), defined=True, scores=v, n_det=n, status=ACTIVE,
                            first_session=0, last_session=0)
    mapper, res = empty_frame(smap, cfg, session=0)
    assert list(mapper.map.objects.status[:2]) == ([ACTIVE, ACTIVE] if apart else [ACTIVE, MERGED])
    assert res.merged == (0 if apart else 1)


def test_a_tentative_object_takes_no_part():
    """stand_pairs with tentative flags: the foot (1) under the screen (0) is its part unless the
    screen, the larger one, is tentative; the foot's own state does not matter."""
    rows = [0, 1]
    for tentative, expected in (([False, False], [(0, 1)]), ([True, False], []),
                                ([False, True], [(0, 1)]), ([True, True], [])):
        pairs = stand_pairs(boxes(rows), TOP[rows], 0.05, 0.05, tentative=np.array(tentative))
        assert [(a, b) for _, a, b in pairs] == expected, tentative


@pytest.mark.parametrize("confirmed", [True, False])
def test_through_the_mapper_a_one_detection_object_does_not_take_a_mouse(confirmed):
    """Both objects made in this session (0): the larger one (the screen's box, here a phantom's)
    detected once, so tentative under min_detections 2; the mouse under it detected 7 times. With
    stand_confirmed the mouse stays a mouse; without it, it goes into the larger one as its foot.
    With the larger one detected twice (no longer tentative) it does either way."""
    for screen_det, merged in ((1, not confirmed), (2, True)):
        cfg = defaults()
        cfg["association"]["stand_gap"] = 0.05
        cfg["association"]["stand_margin"] = 0.05
        cfg["association"]["stand_confirmed"] = confirmed
        assert cfg["maintenance"]["min_detections"] == 2
        smap = SemanticMap.new(CLASSES)
        for i, n_det in ((0, screen_det), (1, 7)):
            smap.objects.append(center=np.array(CENTER[i], float), yaw=0.0, size=np.array(SIZE[i], float),
                                visible=np.ones(8, bool), defined=True, scores=class_vector(TOP[i]), n_det=n_det,
                                status=ACTIVE, first_session=0, last_session=0)
        mapper, res = empty_frame(smap, cfg, session=0)
        assert list(mapper.map.objects.status[:2]) == ([ACTIVE, MERGED] if merged else [ACTIVE, ACTIVE]), screen_det
        assert res.merged == int(merged)


def test_a_foot_plate_out_in_front_of_a_thin_screen_is_its_foot():
    """stand_within_floor (thirty-seventh round): a screen box 0.5 m long (along x) and 0.14 m deep
    (x 1.75..2.25, y -0.07..0.07, z 0.82..1.22) and a foot plate 0.25 x 0.11 x 0.05 m (z 0.75..0.80,
    its top 0.02 under the screen) whose centre stands 0.10 m in front of the screen's middle (y
    0.10): 0.10 / 0.14 = 0.71 of the depth, over stand_within's 0.5 (0.07 m), under a floor of 0.12
    m. Half of its footprint lies under the screen grown by 0.1 per side (y up to 0.17: all of
    it). At 0.13 m in front the floor does not take it either."""
    def pairs(y, floor):
        b = Boxes(np.array([[2.0, 0.0, 1.02], [2.0, y, 0.775]]), np.zeros(2),
                  np.array([[0.5, 0.14, 0.4], [0.25, 0.11, 0.05]]), np.ones((2, 8), bool))
        return [(a, c) for _, a, c in stand_pairs(b, np.array([TV, MOUSE]), 0.08, 0.1, low=0.3, within=0.5,
                                                  within_floor=floor)]

    assert pairs(0.10, 0.0) == []
    assert pairs(0.10, 0.12) == [(0, 1)]
    assert pairs(0.13, 0.12) == []
    assert pairs(0.06, 0.0) == [(0, 1)]  # 0.43 of the depth: the share alone


def test_centred_under_with_a_floor_by_hand():
    """Box 1 0.5 x 0.14 at the origin (yaw 0). A centre 0.10 m along y: 0.71 of its width, over 0.5,
    under a floor of 0.12 m; the floor says nothing along the length (0.3 m along x: 0.6 > 0.5)."""
    def under(xy, floor):
        b = Boxes(np.array([[xy[0], xy[1], 0.05], [0.0, 0.0, 0.2]]), np.zeros(2),
                  np.array([[0.05, 0.05, 0.1], [0.5, 0.14, 0.4]]), np.ones((2, 8), bool))
        return bool(centred_under(b, 0.5, 0.5, floor)[0, 1])

    assert not under((0.0, 0.10), 0.0)
    assert under((0.0, 0.10), 0.12)
    assert not under((0.3, 0.0), 0.12)

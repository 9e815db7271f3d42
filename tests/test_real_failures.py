"""The failure modes seen on real recordings (issue 9), on hand-built scenes: geometry is never taken
from a different object, people never become objects, partial views of one long object join."""

import numpy as np

from ltc_cli import plugins
from ltc_cli.config import defaults
from ltc_cli.geometry.boxes import Boxes
from ltc_cli.map.model import ACTIVE, SemanticMap, top_class
from ltc_cli.pipeline.association import adjoining_partial, footprint_gaps, similar_volume
from ltc_cli.pipeline.mapper import Mapper
from tests.scene import INTR, T_world_camera, render

CLASSES = ["cup", "dining table", "person"]
CUP, TABLE, PERSON = [1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, 1.0, 0]


def make_mapper(cfg=None):
    cfg = cfg or defaults()
    smap = SemanticMap.new(CLASSES)
    metric = plugins.get("metrics", "vertex").factory(cfg["association"])
    policy = plugins.get("policies", "non-detection").factory(cfg["maintenance"])
    return Mapper(smap, cfg, metric, policy)


def add_object(mapper, center, size, scores, n_det, defined):
    t = mapper.map.objects
    row = t.append(center=center, yaw=0.0, size=size, visible=np.ones(8, bool), defined=defined,
                   scores=scores, n_det=n_det, n_nondet=0, status=ACTIVE)
    mapper.index.insert(row, np.asarray(center, float), np.asarray(size, float))
    return row


def frame(mapper, boxes, scores, i=1):
    depth, masks = render(boxes, wall_x=4.0)
    return mapper.process_frame(i, f"f{i}", masks, [np.asarray(s, float) for s in scores], depth,
                                T_world_camera(), INTR, (0.3, 6.0))


def test_a_cup_inside_a_partial_table_leaves_the_table_box_unchanged():
    mapper = make_mapper()
    # A partial table 1.6 x 1.0 x 0.75 m (as a first, partial view leaves it) around x 2.5 m.
    table = add_object(mapper, [2.5, 0.0, 0.375], [1.0, 1.6, 0.75], TABLE, n_det=3, defined=False)
    before = (mapper.map.objects.center[table].copy(), mapper.map.objects.size[table].copy())
    # A cup 8 x 8 x 10 cm standing inside the table's box (on it), seen whole.
    res = frame(mapper, [(2.2, 2.28, -0.04, 0.04, 0.6, 0.7)], [CUP])
    t = mapper.map.objects
    np.testing.assert_array_equal(t.center[table], before[0])
    np.testing.assert_array_equal(t.size[table], before[1])
    assert res.created == 1  # the cup is an object of its own ...
    cup = np.flatnonzero((t.status == ACTIVE) & (top_class(t.scores) == 0))
    assert len(cup) == 1 and t.size[cup[0]].max() < 0.3
    # ... and stays one after the in-view merge (the kitchen's table took a cup's box through it).
    frame(mapper, [(2.2, 2.28, -0.04, 0.04, 0.6, 0.7)], [CUP], i=2)
    np.testing.assert_array_equal(t.size[table], before[1])
    assert t.status[cup[0]] == ACTIVE and t.status[table] == ACTIVE


def test_a_defined_cup_object_never_reshapes_the_table_it_stands_in():
    mapper = make_mapper()
    table = add_object(mapper, [2.5, 0.0, 0.375], [1.0, 1.6, 0.75], TABLE, n_det=3, defined=False)
    cup = add_object(mapper, [2.24, 0.0, 0.65], [0.08, 0.08, 0.1], CUP, n_det=3, defined=True)
    size = mapper.map.objects.size[table].copy()
    frame(mapper, [], [])  # nothing detected; the merge step sees both objects in view
    t = mapper.map.objects
    np.testing.assert_array_equal(t.size[table], size)
    assert t.status[cup] == ACTIVE


def test_a_person_detection_never_becomes_an_object():
    mapper = make_mapper()
    res = frame(mapper, [(2.0, 2.4, -0.3, 0.3, 0.0, 1.7)], [PERSON])
    assert res.created == 0 and mapper.map.objects.n == 0
    cfg = defaults()
    cfg["map"]["moving_classes"] = []  # the setting that keeps them
    mapper = make_mapper(cfg)
    assert frame(mapper, [(2.0, 2.4, -0.3, 0.3, 0.0, 1.7)], [PERSON]).created == 1


def test_similar_volume_by_hand():
    # 1 m^3 against 0.25 m^3 (ratio 0.25) and 0.001 m^3 (a cup; 0.001).
    ok = similar_volume(np.array([1.0, 1.0]), np.array([0.25, 0.001]), 0.1)
    assert ok.tolist() == [True, False]
    assert similar_volume(np.array([1.0]), np.array([0.001]), None).tolist() == [True]


def test_footprint_gap_by_hand_and_adjoining_partial_views():
    # Unit boxes along x: one at x 0..1, the others at x 1.03..2.03 (gap 0.03), 1.5..2.5 (0.5)
    # and overlapping 0.5..1.5 (0); a fourth at the first's place but 2 m higher (z apart: inf).
    det = Boxes(np.array([[0.5, 0, 0.5]]), np.zeros(1), np.ones((1, 3)), np.ones((1, 8), bool))
    cands = Boxes(np.array([[1.53, 0, 0.5], [2.0, 0, 0.5], [1.0, 0, 0.5], [0.5, 0, 2.8]]), np.zeros(4),
                  np.ones((4, 3)), np.ones((4, 8), bool))
    gaps = footprint_gaps(det, cands)
    np.testing.assert_allclose(gaps[:3], [0.03, 0.5, 0.0], atol=1e-12)
    assert np.isinf(gaps[3])
    same = np.array([True, True, False, True])
    partial = np.array([True, True, True, True])
    assert adjoining_partial(gaps, same, partial, 0.05) == 0
    assert adjoining_partial(gaps, same, np.array([False, True, True, True]), 0.05) == -1
    assert adjoining_partial(gaps, same, partial, None) == -1


def test_adjoining_gap_grows_with_the_longer_side_by_hand():
    # Gaps 0.09 m to three partial candidates; the longer footprint side of each pair 1.6 m (a
    # table's end against its other end), 0.5 m (two chairs side by side) and 0.4 m.
    gaps = np.array([0.09, 0.09, 0.04])
    long_sides = np.array([1.6, 0.5, 0.4])
    partial = np.ones(3, bool)
    # share 0.1: allowed 0.16, max(0.05, 0.05) = 0.05, 0.05 -> the table end and the 4 cm one.
    assert adjoining_partial(gaps, np.array([True, True, False]), partial, 0.05, long_sides, 0.1) == 0
    assert adjoining_partial(gaps, np.array([False, True, True]), partial, 0.05, long_sides, 0.1) == 2
    assert adjoining_partial(gaps[:2], np.array([False, True]), partial[:2], 0.05, long_sides[:2], 0.1) == -1
    # Without the share only the fixed gap counts.
    assert adjoining_partial(gaps, np.array([True, True, False]), partial, 0.05, long_sides, None) == -1


def test_a_table_end_nine_centimetres_from_its_other_end_joins_it():
    # The dining room driven backwards: the table's far end (a partial object, y -0.5..0.11 m)
    # was mapped first; now its near part is seen cut by the image's left edge (y 0.2..1.6 m in
    # view at 2.5 m), its footprint about 9 cm from the object's: beyond the fixed 5 cm gap,
    # within a tenth of its 1.4 m side. The far end stands in the depth too (undetected in this
    # frame): where the depth saw through it, free-space carving would cut the union back.
    def run(share):
        cfg = defaults()
        cfg["association"]["partial_adjoin_share"] = None if share is None else {"dining table": share}
        mapper = make_mapper(cfg)
        end = add_object(mapper, [3.0, -0.195, 0.375], [1.0, 0.61, 0.75], TABLE, n_det=2, defined=False)
        depth, masks = render([(2.5, 3.5, 0.2, 2.5, 0.0, 0.75), (2.5, 3.5, -0.5, 0.11, 0.0, 0.75)], wall_x=4.0)
        res = mapper.process_frame(1, "f1", masks[:1], [np.asarray(TABLE, float)], depth, T_world_camera(), INTR,
                                   (0.3, 6.0))
        return mapper, end, res

    mapper, end, res = run(0.1)
    t = mapper.map.objects
    assert res.created == 0 and t.n_det[end] == 3
    assert t.size[end, :2].max() > 1.9  # the union of both parts
    mapper, end, res = run(None)
    assert res.created == 1 and mapper.map.objects.n_det[end] == 2

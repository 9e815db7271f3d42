"""Tests of ltc_cli.evaluation against independent values (shapely polygons, hand computations)."""


import numpy as np
import pytest
from shapely.geometry import Polygon

from ltc_cli.errors import LtcError
from ltc_cli.geometry.polygons import convex_intersection_area, pairwise_ious_arrays
from ltc_cli.tools.evaluate import evaluate, pairwise_ious, volume_iou, xy_iou
from ltc_cli.geometry.boxes import box_corners


def _shapely_ious(a, b):
    """Reference XY IoU and VIoU from shapely footprints (an independent implementation)."""
    pa = Polygon(box_corners(*a)[:4, :2])
    pb = Polygon(box_corners(*b)[:4, :2])
    inter = pa.intersection(pb).area
    union = pa.area + pb.area - inter
    za = (a[0][2] - a[2][2] / 2, a[0][2] + a[2][2] / 2)
    zb = (b[0][2] - b[2][2] / 2, b[0][2] + b[2][2] / 2)
    dz = max(0.0, min(za[1], zb[1]) - max(za[0], zb[0]))
    vi = inter * dz
    vu = pa.area * a[2][2] + pb.area * b[2][2] - vi
    return (inter / union if union > 0 else 0.0), (vi / vu if vu > 0 else 0.0)


def _random_box(rng, spread=1.0):
    return (
        rng.uniform(-spread, spread, 3),
        float(rng.uniform(-np.pi / 2, np.pi / 2)),
        rng.uniform(0.05, 1.5, 3),
    )


def test_hand_cases():
    a = ((0.0, 0.0, 0.5), 0.0, (1.0, 1.0, 1.0))
    assert xy_iou(a, a) == pytest.approx(1.0, abs=1e-12)
    assert volume_iou(a, a) == pytest.approx(1.0, abs=1e-12)
    # Disjoint, and touching along an edge: 0.
    assert xy_iou(a, ((3.0, 0.0, 0.5), 0.3, (1.0, 1.0, 1.0))) == 0.0
    assert xy_iou(a, ((1.0, 0.0, 0.5), 0.0, (1.0, 1.0, 1.0))) == pytest.approx(0.0, abs=1e-12)
    # Half shifted: intersection 0.5, union 1.5.
    assert xy_iou(a, ((0.5, 0.0, 0.5), 0.0, (1.0, 1.0, 1.0))) == pytest.approx(1 / 3)
    # A unit square and its copy turned by 45 degrees: the intersection is a regular octagon of
    # area 2 (sqrt2 - 1) (four corner triangles with legs 1 - sqrt2/2 cut off), the union
    # 2 - 2 (sqrt2 - 1), so IoU = (sqrt2 - 1) / (2 - sqrt2) = 1 / sqrt2.
    b = ((0.0, 0.0, 0.5), np.pi / 4, (1.0, 1.0, 1.0))
    assert xy_iou(a, b) == pytest.approx(1 / np.sqrt(2), abs=1e-12)
    assert volume_iou(a, b) == pytest.approx(1 / np.sqrt(2), abs=1e-12)
    # Same footprints, z intervals [0, 1] and [0.5, 2.5]: overlap 0.5 -> 0.5 / (1 + 2 - 0.5).
    c = ((0.0, 0.0, 1.5), 0.0, (1.0, 1.0, 2.0))
    assert volume_iou(a, c) == pytest.approx(0.5 / 2.5)
    assert xy_iou(a, c) == pytest.approx(1.0)
    # The 45-degree copy, taller and lifted: octagon area x z overlap 0.5.
    d = ((0.0, 0.0, 1.5), np.pi / 4, (1.0, 1.0, 2.0))
    oct_area = 2 * (np.sqrt(2) - 1)
    assert volume_iou(a, d) == pytest.approx(oct_area * 0.5 / (1 + 2 - oct_area * 0.5))
    # Yaw and yaw + pi / 2 with swapped sizes are the same box.
    e = ((0.2, 0.1, 0.0), 0.3, (2.0, 0.5, 1.0))
    f = ((0.2, 0.1, 0.0), 0.3 - np.pi / 2, (0.5, 2.0, 1.0))
    assert xy_iou(e, f) == pytest.approx(1.0, abs=1e-12)
    # A zero-size box overlaps nothing.
    assert xy_iou(a, ((0.0, 0.0, 0.5), 0.0, (0.0, 0.0, 0.0))) == 0.0
    # Dict boxes work as well.
    assert xy_iou({"center": a[0], "yaw": a[1], "size": a[2]}, b) == pytest.approx(1 / np.sqrt(2))


def test_random_boxes_match_shapely():
    rng = np.random.default_rng(1)
    for _ in range(400):
        a, b = _random_box(rng, 0.8), _random_box(rng, 0.8)
        ref_xy, ref_v = _shapely_ious(a, b)
        assert xy_iou(a, b) == pytest.approx(ref_xy, abs=1e-9)
        assert volume_iou(a, b) == pytest.approx(ref_v, abs=1e-9)
        assert xy_iou(b, a) == pytest.approx(ref_xy, abs=1e-9)


def test_far_from_origin_is_precise():
    rng = np.random.default_rng(2)
    for _ in range(50):
        a, b = _random_box(rng, 0.5), _random_box(rng, 0.5)
        ref_xy, _ = _shapely_ious(a, b)
        shift = np.array([1000.0, -2000.0, 0.0])
        a2, b2 = (a[0] + shift, a[1], a[2]), (b[0] + shift, b[1], b[2])
        assert xy_iou(a2, b2) == pytest.approx(ref_xy, abs=1e-7)


def test_pairwise_matches_single_and_is_fast():
    rng = np.random.default_rng(3)
    boxes_a = [_random_box(rng, 3.0) for _ in range(40)]
    boxes_b = [_random_box(rng, 3.0) for _ in range(30)]
    xy, vol = pairwise_ious(boxes_a, boxes_b)
    assert xy.shape == (40, 30) and vol.shape == (40, 30)
    for i in range(0, 40, 7):
        for j in range(30):
            ref_xy, ref_v = _shapely_ious(boxes_a[i], boxes_b[j])
            assert xy[i, j] == pytest.approx(ref_xy, abs=1e-9)
            assert vol[i, j] == pytest.approx(ref_v, abs=1e-9)
    # geometry.Boxes (arrays) give the same matrix.
    from ltc_cli.geometry.boxes import Boxes

    arr = Boxes(
        np.array([b[0] for b in boxes_a]), np.array([b[1] for b in boxes_a]),
        np.array([b[2] for b in boxes_a]), np.ones((40, 8), dtype=bool),
    )
    xy2, vol2 = pairwise_ious(arr, boxes_b)
    assert np.array_equal(xy, xy2) and np.array_equal(vol, vol2)
    # A few hundred by a few hundred in a house-sized area.
    M, G = 300, 300
    ca, cb = rng.uniform(0, 20, (M, 3)), rng.uniform(0, 20, (G, 3))
    ya, yb = rng.uniform(-1.5, 1.5, M), rng.uniform(-1.5, 1.5, G)
    sa, sb = rng.uniform(0.1, 2.0, (M, 3)), rng.uniform(0.1, 2.0, (G, 3))
    # (Its speed is benchmarks/bench_speed.py's to measure, not a test's.)
    xy, _ = pairwise_ious_arrays(ca, ya, sa, cb, yb, sb)
    assert xy.shape == (M, G)
    i, j = np.argwhere(xy > 0)[0]
    ref_xy, _ = _shapely_ious((ca[i], ya[i], sa[i]), (cb[j], yb[j], sb[j]))
    assert xy[i, j] == pytest.approx(ref_xy, abs=1e-9)


def test_convex_intersection_area_polygons():
    tri = np.array([[[0.0, 0.0], [2.0, 0.0], [0.0, 2.0]]])
    sq = np.array([[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]])
    # The unit square lies inside the triangle x + y <= 2.
    assert convex_intersection_area(sq, tri)[0] == pytest.approx(1.0)
    assert convex_intersection_area(tri, sq)[0] == pytest.approx(1.0)


@pytest.mark.parametrize("pairs", [1, 3, 8, 32, 40])
def test_convex_intersection_area_of_few_and_many_pairs_matches_shapely(pairs, monkeypatch):
    """Up to ``FEW_PAIRS`` (32) pairs are clipped in plain floats, more at once in numpy
    (forty-fifth round): either way each area is shapely's, and the plain-float areas are the
    vectorised ones within a rounding (the vectorised sum's order depends on the largest polygon
    in its batch). Among the pairs: two identical rectangles, one inside another, two that touch
    at an edge, and two apart."""
    from ltc_cli.geometry import polygons
    from ltc_cli.geometry.boxes import box_corners

    rng = np.random.default_rng(pairs)
    center = rng.uniform(-0.5, 0.5, (2, pairs, 3))
    yaw = rng.uniform(-np.pi, np.pi, (2, pairs))
    size = rng.uniform(0.05, 1.5, (2, pairs, 3))
    special = [(center[0, 0], yaw[0, 0], size[0, 0]),  # identical
               (center[0, 0], yaw[0, 0], size[0, 0] / 2),  # inside
               (center[0, 0] + [size[0, 0, 0], 0, 0], 0.0, size[0, 0]),  # edge to edge (yaw 0 below)
               (center[0, 0] + [5.0, 0, 0], yaw[0, 0], size[0, 0])]  # apart
    for k, (c, y, sz) in enumerate(special[:pairs]):
        center[1, k], yaw[1, k], size[1, k] = c, y, sz
        if k == 2:
            center[0, k], yaw[0, k], size[0, k] = center[0, 0], 0.0, size[0, 0]
    foot_a = box_corners(center[0], yaw[0], size[0])[:, :4, :2]
    foot_b = box_corners(center[1], yaw[1], size[1])[:, :4, :2]
    areas = convex_intersection_area(foot_a, foot_b)
    reference = [Polygon(a).intersection(Polygon(b)).area for a, b in zip(foot_a, foot_b)]
    assert areas == pytest.approx(reference, abs=1e-12)
    if pairs <= polygons.FEW_PAIRS:
        monkeypatch.setattr(polygons, "FEW_PAIRS", 0)  # the same pairs through numpy
        assert areas == pytest.approx(convex_intersection_area(foot_a, foot_b), rel=1e-14, abs=1e-15)


def _obj(oid, cls, x, y, yaw=0.0, size=(1.0, 1.0, 1.0), z=0.5, **kw):
    return {"id": oid, "class": cls, "center": [x, y, z], "yaw": yaw, "size": list(size), **kw}


def test_precision_recall_f1_by_hand():
    gt = [
        _obj(1, "chair", 0, 0),
        _obj(2, "chair", 5, 0),
        _obj(3, "couch", 0, 5, size=(2.0, 1.0, 1.0)),
        _obj(4, "tv", 10, 10),
    ]
    maps = [
        _obj(101, "chair", 0.5, 0),  # TP with gt 1: IoU 1/3, position error 0.5
        _obj(102, "chair", 5, 0),  # TP with gt 2: IoU 1, position error 0
        _obj(103, "couch", 0, 5.5, size=(2.0, 1.0, 1.0)),  # TP with gt 3: IoU 1/3, error 0.5
        _obj(104, "tv", 0, 5),  # wrong class on the couch: FP
        _obj(105, "bed", 20, 20),  # nothing there: FP
    ]
    r = evaluate(maps, gt)
    assert (r["tp"], r["fp"], r["fn"]) == (3, 2, 1)
    assert r["precision"] == pytest.approx(3 / 5)
    assert r["recall"] == pytest.approx(3 / 4)
    assert r["f1"] == pytest.approx(2 * 0.6 * 0.75 / (0.6 + 0.75))
    assert r["mean_xy_iou"] == pytest.approx((1 / 3 + 1 + 1 / 3) / 3)
    assert r["mean_viou"] == pytest.approx((1 / 3 + 1 + 1 / 3) / 3)
    assert r["mean_position_error"] == pytest.approx((0.5 + 0 + 0.5) / 3)
    assert sorted(r["fp_ids"]) == [104, 105] and r["fn_ids"] == [4]
    assert r["duplicates"] == 0 and r["ghosts"] == 0
    chair = r["per_class"]["chair"]
    assert (chair["tp"], chair["fp"], chair["fn"]) == (2, 0, 0)
    assert chair["precision"] == 1.0 and chair["recall"] == 1.0
    tv = r["per_class"]["tv"]
    assert (tv["tp"], tv["fp"], tv["fn"]) == (0, 1, 1) and tv["mean_xy_iou"] is None
    # bed: one FP and no ground truth: recall 0/0 is undefined (None), precision 0/1 = 0.
    assert r["per_class"]["bed"]["recall"] is None and r["per_class"]["bed"]["precision"] == 0.0


def test_duplicate_counts_as_fp():
    gt = [_obj(1, "couch", 0, 0, size=(2.0, 1.0, 1.0))]
    maps = [
        _obj(10, "couch", 0.1, 0, size=(2.0, 1.0, 1.0)),  # the better match
        _obj(11, "couch", 0.8, 0, size=(1.0, 1.0, 1.0)),  # a partial view kept as a second object
    ]
    r = evaluate(maps, gt)
    assert r["matches"][0]["map_id"] == 10 and r["matches"][0]["gt_id"] == 1
    assert (r["tp"], r["fp"], r["fn"]) == (1, 1, 0)
    assert r["duplicates"] == 1 and r["duplicate_ids"] == [11]
    assert r["duplicate_ratio"] == pytest.approx(0.5)
    assert r["precision"] == pytest.approx(0.5) and r["recall"] == 1.0


def test_center_distance_limit():
    gt = [_obj(1, "bed", 0, 0, size=(8.0, 8.0, 1.0))]
    maps = [_obj(2, "bed", 3.5, 0, size=(1.0, 1.0, 1.0))]  # overlaps, but 3.5 m from the centre
    assert evaluate(maps, gt)["tp"] == 0
    assert evaluate(maps, gt, max_center_distance=4.0)["tp"] == 1


def test_ghost_of_moved_and_removed_objects():
    lap1 = [_obj(1, "chair", 0, 0), _obj(2, "potted plant", 4, 0), _obj(3, "tv", 8, 0)]
    lap2 = {
        "objects": [_obj(1, "chair", 2, 0), _obj(3, "tv", 8, 0)],
        "changes": {"moved": [1], "removed": [2], "added": []},
    }
    maps = [
        _obj(10, "chair", 0.1, 0),  # the chair where it was: ghost
        _obj(11, "chair", 2, 0),  # the chair where it is: TP
        _obj(12, "potted plant", 4, 0.1),  # the removed plant still in the map: ghost
        _obj(13, "tv", 8, 0),  # TP
        _obj(14, "tv", 8.2, 0),  # a duplicate of the tv (the tv did not move)
    ]
    r = evaluate(maps, lap2, previous_gt=lap1)
    assert (r["tp"], r["fp"], r["fn"]) == (2, 3, 0)
    assert sorted(r["ghost_ids"]) == [10, 12] and r["ghosts"] == 2
    assert r["duplicate_ids"] == [14]
    assert r["ghost_ratio"] == pytest.approx(2 / 5)
    # Without the changes recorded they are inferred from the two laps.
    r2 = evaluate(maps, lap2["objects"], previous_gt=lap1)
    assert sorted(r2["ghost_ids"]) == [10, 12]
    # Without the previous lap there are no ghosts to speak of.
    assert evaluate(maps, lap2)["ghosts"] == 0


def test_seen_only_excludes_unseen_ground_truth():
    gt = [
        _obj(1, "chair", 0, 0, seen_pixels=5000),
        _obj(2, "chair", 5, 0, seen_pixels=0),  # never in view
        _obj(3, "cup", 9, 0, size=(0.1, 0.1, 0.1), seen_pixels=0),  # never in view, but mapped
    ]
    maps = [_obj(10, "chair", 0, 0), _obj(11, "cup", 9, 0, size=(0.1, 0.1, 0.1))]
    r = evaluate(maps, gt)
    assert (r["tp"], r["fn"]) == (2, 1) and r["recall"] == pytest.approx(2 / 3)
    r = evaluate(maps, gt, seen_only=True)
    assert (r["tp"], r["fp"], r["fn"]) == (2, 0, 0)
    assert r["recall"] == 1.0 and r["ignored_gt_ids"] == [2]
    # A threshold above 0.
    gt[0]["seen_pixels"] = 50
    r = evaluate([], gt, seen_only=True, min_seen_pixels=100)
    assert (r["fn"], r["ignored_gt"], r["recall"], r["precision"]) == (0, 3, None, None)


def test_greedy_matching_is_one_to_one():
    gt = [_obj(1, "chair", 0, 0), _obj(2, "chair", 0.9, 0)]
    maps = [_obj(10, "chair", 0.45, 0), _obj(11, "chair", 1.0, 0)]
    r = evaluate(maps, gt)
    pairs = sorted((m["map_id"], m["gt_id"]) for m in r["matches"])
    # 11-2 has the best IoU (0.9 / 1.1); then 10 takes the remaining gt 1.
    assert pairs == [(10, 1), (11, 2)]


def test_empty_and_bad_inputs():
    r = evaluate([], [])
    assert r["tp"] == r["fp"] == r["fn"] == 0 and r["precision"] is None  # 0/0: undefined
    assert r["mean_xy_iou"] is None and r["per_class"] == {}
    with pytest.raises(LtcError):
        evaluate([{"id": 1, "class": "chair", "center": [0, 0], "yaw": 0, "size": [1, 1, 1]}], [])
    with pytest.raises(LtcError):
        evaluate([{"id": 1, "center": [0, 0, 0], "yaw": 0, "size": [1, 1, 1]}], [])
    with pytest.raises(LtcError):
        evaluate([], [], max_center_distance=0)


# ---------------------------------------------------------------------------------------------
# IoU thresholds, ghosts of any earlier lap, objects deleted while present, ids kept, 0/0


def _shapely_xy_iou(a, b):
    """XY IoU of two _obj dicts with shapely (independent of ltc's clipping)."""
    return _shapely_ious((a["center"], a["yaw"], a["size"]), (b["center"], b["yaw"], b["size"]))[0]


def test_iou_thresholds_change_tp_counts_by_hand():
    gt = [_obj(1, "chair", 0, 0), _obj(2, "chair", 5, 0), _obj(3, "chair", 10, 0),
          _obj(4, "chair", 15, 0), _obj(5, "tv", 20, 0, seen_pixels=0)]
    maps = [
        _obj(11, "chair", 0, 0),  # exact: IoU 1
        _obj(12, "chair", 5.5, 0),  # half shifted: 0.5 / 1.5 = 1/3
        _obj(13, "chair", 10.7, 0),  # 0.3 / 1.7 = 0.176
        _obj(14, "chair", 15, 0, yaw=np.pi / 4),  # turned 45 degrees: 1 / sqrt2
        _obj(15, "tv", 20.6, 0.6),  # 0.16 / 1.84 = 0.087, on a tv the robot never saw
    ]
    ious = {m["id"]: _shapely_xy_iou(m, g) for m, g in zip(maps, gt)}
    assert ious[12] == pytest.approx(1 / 3) and ious[13] == pytest.approx(0.3 / 1.7)
    assert ious[14] == pytest.approx(1 / np.sqrt(2)) and ious[15] == pytest.approx(0.16 / 1.84)
    r = evaluate(maps, gt)
    assert r["iou_measure"] == "xy_iou" and set(r["at_iou"]) == {"0.25", "0.5"}
    # Any overlap: all five match. IoU > 0.25: 11, 12, 14. IoU > 0.5: 11, 14.
    for level, t, expect in ((r, 0.0, 5), (r["at_iou"]["0.25"], 0.25, 3), (r["at_iou"]["0.5"], 0.5, 2)):
        assert sum(v > t for v in ious.values()) == expect  # shapely agrees with the hand values
        assert (level["tp"], level["fp"], level["fn"]) == (expect, 5 - expect, 5 - expect)
        assert level["precision"] == pytest.approx(expect / 5) and level["recall"] == pytest.approx(expect / 5)
        assert level["f1"] == pytest.approx(expect / 5)
    strict = r["at_iou"]["0.5"]
    assert strict["mean_xy_iou"] == pytest.approx((1 + 1 / np.sqrt(2)) / 2)
    assert sorted(strict["fn_ids"]) == [2, 3, 5]
    assert strict["per_class"]["chair"]["tp"] == 2 and strict["per_class"]["tv"]["tp"] == 0
    # recall over seen objects: the tv was never seen, so it is not an FN there.
    assert r["recall_seen"] == pytest.approx(5 / 5)
    assert r["at_iou"]["0.25"]["recall_seen"] == pytest.approx(3 / 4)
    assert r["at_iou"]["0.5"]["recall_seen"] == pytest.approx(2 / 4)
    assert r["at_iou"]["0.5"]["f1_seen"] == pytest.approx(2 * 2 / (2 * 2 + 3 + 2))
    # Other levels on request.
    r = evaluate(maps, gt, iou_thresholds=(0.1, 0.7))
    assert r["at_iou"]["0.1"]["tp"] == 4 and r["at_iou"]["0.7"]["tp"] == 2


def test_threshold_matches_are_the_any_overlap_matches_above_it():
    """Re-matching with IoU > t as the candidate condition equals filtering the any-overlap
    matches by IoU > t (greedy by IoU), on random crowded scenes."""
    rng = np.random.default_rng(7)
    for _ in range(20):
        gt = [_obj(j, str(rng.integers(2)), *rng.uniform(0, 4, 2), yaw=float(rng.uniform(-1.5, 1.5)),
                   size=rng.uniform(0.3, 1.2, 3)) for j in range(12)]
        maps = [_obj(100 + i, str(rng.integers(2)), *rng.uniform(0, 4, 2), yaw=float(rng.uniform(-1.5, 1.5)),
                     size=rng.uniform(0.3, 1.2, 3)) for i in range(12)]
        r = evaluate(maps, gt)
        for t, level in r["at_iou"].items():
            above = [m for m in r["matches"] if m["xy_iou"] > float(t)]
            assert level["tp"] == len(above)
            assert level["fp"] == 12 - len(above) and level["fn"] == 12 - len(above)


def _gt_doc(objects, changes=None, lap=1):
    doc = {"format": "ltc-ground-truth/1", "lap": lap, "objects": objects}
    if changes is not None:
        doc["changes"] = changes
    return doc


def _three_laps():
    """lap1: chair 1, plant 2, tv 3, chair 4; lap2: plant removed, chair 4 moved 2 m;
    lap3: nothing changes but chair 4 goes back to its lap-1 place."""
    lap1 = _gt_doc([_obj(1, "chair", 0, 0), _obj(2, "potted plant", 4, 0), _obj(3, "tv", 8, 0),
                    _obj(4, "chair", 12, 0)], lap=1)
    lap2 = _gt_doc([_obj(1, "chair", 0, 0), _obj(3, "tv", 8, 0), _obj(4, "chair", 14, 0)],
                   {"moved": [4], "removed": [2], "added": []}, lap=2)
    lap3 = _gt_doc([_obj(1, "chair", 0, 0), _obj(3, "tv", 8, 0), _obj(4, "chair", 12, 0)],
                   {"moved": [4], "removed": [], "added": []}, lap=3)
    maps = [
        _obj(10, "chair", 0, 0),  # TP
        _obj(11, "potted plant", 4, 0.1),  # the plant removed in lap 2, still mapped: ghost of lap 1
        _obj(12, "tv", 8, 0),  # TP
        _obj(13, "chair", 12, 0),  # chair 4 back at its lap-1 place: TP, not a ghost
        _obj(14, "chair", 14.1, 0),  # chair 4's lap-2 place: ghost of lap 2
    ]
    return lap1, lap2, lap3, maps


def test_ghost_of_any_earlier_lap():
    lap1, lap2, lap3, maps = _three_laps()
    r = evaluate(maps, lap3, previous_gt=[lap1, lap2])
    assert (r["tp"], r["fp"], r["fn"]) == (3, 2, 0)
    assert r["ghost_ids"] == [11, 14] and r["ghosts"] == 2 and r["earlier_laps"] == 2
    assert r["ghost_ratio"] == pytest.approx(2 / 5) and r["duplicates"] == 0
    # Only the previous lap (today's behaviour): the plant of lap 1 is a plain false positive.
    r = evaluate(maps, lap3, previous_gt=lap2)
    assert r["ghost_ids"] == [14] and r["earlier_laps"] == 1
    assert 11 in r["fp_ids"] and r["duplicate_ids"] == []
    # Lists of objects work as laps too, and the changes are inferred from the boxes.
    r = evaluate(maps, lap3["objects"], previous_gt=[lap1["objects"], lap2["objects"]])
    assert r["ghost_ids"] == [11, 14]
    r = evaluate(maps, lap3, previous_gt=[])
    assert r["ghosts"] == 0 and r["earlier_laps"] == 0


def test_former_places_tolerance():
    from ltc_cli.tools.evaluate import as_eval_object
    from ltc_cli.tools.lap_history import former_places

    before = [as_eval_object(_obj(1, "chair", 0, 0)), as_eval_object(_obj(2, "chair", 5, 0))]
    now = [as_eval_object(_obj(1, "chair", 0.08, 0)), as_eval_object(_obj(2, "chair", 5.15, 0))]
    # Chair 1 moved 8 cm (still there), chair 2 15 cm (a former place).
    assert [o.id for o in former_places(now, [before])] == [2]
    # A move the ground truth lists counts even when small.
    assert [o.id for o in former_places(now, [before], {"moved": [1]})] == [1, 2]


def test_earlier_laps_are_found_beside_the_recording(tmp_path):
    import json

    from ltc_cli.recordings.groundtruth import earlier_laps

    for k, doc in enumerate(_three_laps()[:3], start=1):
        (tmp_path / f"lap{k}").mkdir()
        (tmp_path / f"lap{k}" / "ground_truth.json").write_text(json.dumps(doc))
    laps = earlier_laps(tmp_path / "lap3")
    assert [d["lap"] for d in laps] == [1, 2]
    assert [d["lap"] for d in earlier_laps(tmp_path / "lap2" / "ground_truth.json")] == [1]
    assert earlier_laps(tmp_path / "lap1") == [] and earlier_laps(tmp_path) == []


def _removal_map():
    """A map whose event log has maintenance removals (detail "other ...") and an unconfirmed one."""
    from ltc_cli.map.model import REMOVED, Event, SemanticMap
    from tests.sample_maps import add

    smap = SemanticMap.new(["chair", "couch", "tv"])
    add(smap, [0, 0, 0.5], 0.0, [1, 1, 1], "chair", 0.8, seen=(1, 10, 1, 20))  # 1: on GT chair 1, made
    # after object 6 (below) was removed at frame 5: rebuilt. (Ids are only for the test's reading.)
    for center, cls in (([3.0, 0, 0.5], "couch"),  # 2: on GT couch 2 (IoU 0.8 / 1.2)
                        ([3.2, 0, 0.5], "couch"),  # 3: rebuilt and deleted again on couch 2
                        ([6.0, 0, 0.5], "tv"),  # 4: unconfirmed removal on GT tv 3: not maintenance
                        ([9.0, 0, 0.5], "chair"),  # 5: removed where nothing is now: rightly
                        ([0.3, 0, 0.5], "chair"),  # 6: an earlier chair 1, deleted and rebuilt as 1
                        ([3.0, 0.1, 0.5], "tv")):  # 7: a tv on the couch: another class
        add(smap, center, 0.0, [1, 1, 1], cls, 0.4, status=REMOVED)
    for oid in (2, 3, 5, 6, 7):
        smap.events.append(Event(1, 5, "lap2/000005", "removed", oid, 0,
                                 "other 0.510 > chair 0.400 after 6 non-detections and 3 detections"))
    smap.events.append(Event(1, 6, "lap2/000006", "removed", 4, 0,
                             "unconfirmed: 1 detection(s) in the session that created it, fewer than 2"))
    gt = _gt_doc([_obj(1, "chair", 0, 0), _obj(2, "couch", 3.1, 0), _obj(3, "tv", 6, 0),
                  _obj(4, "chair", 20, 0)])
    return smap, gt


def test_present_objects_deleted_by_maintenance(tmp_path):
    from ltc_cli.map.store import load_map, save_map
    from ltc_cli.tools.evaluate import evaluate_map
    from ltc_cli.tools.lap_history import maintenance_removed_ids

    smap, gt = _removal_map()
    assert maintenance_removed_ids(smap.events) == [2, 3, 5, 6, 7]
    path = tmp_path / "m.h5"
    save_map(smap, path)
    r = evaluate_map(load_map(path), gt)
    d = r["deleted_while_present"]
    # GT chair 1 (removed object 6) and couch 2 (removed objects 2 and 3); 4 objects present.
    assert d == {"count": 2, "present": 4, "share": 0.5, "gt_ids": [1, 2], "map_ids": [2, 3, 6],
                 "duplicates_removed": [], "lost_gt_ids": [2]}  # the chair was rebuilt (active object 1), the couch not
    assert (r["tp"], r["fp"], r["fn"]) == (1, 0, 3)  # removed objects are not in the map
    # Event dicts (as a JSON export would give) work as well.
    events = [{"kind": e.kind, "object_id": e.object_id, "detail": e.detail} for e in smap.events]
    assert maintenance_removed_ids(events) == [2, 3, 5, 6, 7]


def test_a_removal_is_judged_against_the_lap_it_was_made_in(tmp_path):
    """A chair rightly removed after it was carried away does not count as "deleted while present"
    because a new chair stands at its old place two laps later; a removal while the object stood
    there does, whenever it was made, unless the map object that stands on it now is older than the
    removal (the removed one was a duplicate)."""
    from ltc_cli.map.model import REMOVED, Event, SemanticMap
    from ltc_cli.map.store import load_map, save_map
    from ltc_cli.tools.evaluate import evaluate_map
    from ltc_cli.tools.lap_history import maintenance_removals
    from tests.sample_maps import SESSION, add

    lap1 = _gt_doc([_obj(1, "chair", 0, 0), _obj(2, "chair", 5, 0), _obj(3, "bottle", 8, 0)], lap=1)
    lap2 = _gt_doc([_obj(1, "chair", 0, 0), _obj(3, "bottle", 8, 0)], lap=2)  # chair 2 taken away
    lap3 = _gt_doc([_obj(1, "chair", 0, 0), _obj(3, "bottle", 8, 0), _obj(4, "chair", 5.1, 0)], lap=3)
    smap = SemanticMap.new(["chair", "bottle"])
    smap.sessions = [dict(SESSION) for _ in range(3)]
    add(smap, [0.0, 0, 0.5], 0.0, [1, 1, 1], "chair", 0.8, seen=(1, 0, 2, 9))  # 1: chair 1, rebuilt in lap 2
    add(smap, [5.0, 0, 0.5], 0.0, [1, 1, 1], "chair", 0.4, status=REMOVED)  # 2: chair 2's, lap 2
    add(smap, [0.1, 0, 0.5], 0.0, [1, 1, 1], "chair", 0.4, status=REMOVED)  # 3: chair 1's, lap 1
    add(smap, [8.0, 0, 0.5], 0.0, [1, 1, 1], "bottle", 0.4, status=REMOVED)  # 4: bottle 3's, lap 3
    add(smap, [0.05, 0, 0.5], 0.0, [1, 1, 1], "chair", 0.4, status=REMOVED)  # 5: a second box on chair 1
    for oid, session in ((2, 1), (3, 0), (4, 2), (5, 2)):
        smap.events.append(Event(session, 5, f"lap{session + 1}/000005", "removed", oid, 0,
                                 "other 0.510 > chair 0.400 after 6 non-detections and 3 detections"))
    assert maintenance_removals(smap.events) == {2: (1, 5), 3: (0, 5), 4: (2, 5), 5: (2, 5)}
    path = tmp_path / "m.h5"
    save_map(smap, path)
    smap = load_map(path)
    d = evaluate_map(smap, lap3, [lap1, lap2])["deleted_while_present"]
    assert (d["count"], d["present"], d["gt_ids"], d["map_ids"]) == (2, 3, [1, 3], [3, 4])
    assert d["lost_gt_ids"] == [3]  # the chair has its active map object 1; the bottle has none
    assert d["duplicates_removed"] == [5]  # removed in lap 3, after object 1 was made in lap 2
    # Without the earlier laps every removal is judged against lap 3: chair 4 is counted.
    d = evaluate_map(smap, lap3)["deleted_while_present"]
    assert (d["count"], d["gt_ids"], d["map_ids"], d["duplicates_removed"]) == (3, [1, 3, 4], [2, 3, 4], [5])


def test_a_removed_box_is_the_object_it_was_last_detected_on(tmp_path):
    """A 1 x 1 m plant box built in lap 1 on plant 1 at (0, 0); in lap 2 plant 1 is gone and plant
    2 (1 x 1 m) stands at (0.95, 0), overlapping the box by 0.05 x 1 m (XY IoU 0.05 / 1.95); the map
    removes the box in lap 2. By the lap it was removed in alone, plant 2 is "deleted while
    present"; by the lap of its last detection it was plant 1's box, and plant 1 had gone: rightly
    removed. A second box, last detected in lap 1 on plant 3 that stays put, removed in lap 2,
    counts (plant 3). A third box last detected in lap 2 on nothing of its class counts for nothing."""
    from ltc_cli.map.model import REMOVED, Event, SemanticMap
    from ltc_cli.map.store import load_map, save_map
    from ltc_cli.tools.evaluate import evaluate_map
    from tests.sample_maps import SESSION, add

    lap1 = _gt_doc([_obj(1, "potted plant", 0, 0), _obj(3, "potted plant", 5, 0)], lap=1)
    lap2 = _gt_doc([_obj(2, "potted plant", 0.95, 0), _obj(3, "potted plant", 5, 0)], lap=2)
    smap = SemanticMap.new(["potted plant", "chair"])
    smap.sessions = [dict(SESSION) for _ in range(2)]
    add(smap, [0.0, 0, 0.5], 0.0, [1, 1, 1], "potted plant", 0.4, status=REMOVED, seen=(0, 1, 0, 9))
    add(smap, [5.0, 0, 0.5], 0.0, [1, 1, 1], "potted plant", 0.4, status=REMOVED, seen=(0, 1, 0, 9))
    add(smap, [9.0, 0, 0.5], 0.0, [1, 1, 1], "potted plant", 0.4, status=REMOVED, seen=(1, 1, 1, 9))
    for oid in (1, 2, 3):
        smap.events.append(Event(1, 20, "lap2/000020", "removed", oid, 0,
                                 "other: clearly visible in 5 frames of this session"))
    path = tmp_path / "m.h5"
    save_map(smap, path)
    smap = load_map(path)
    d = evaluate_map(smap, lap2, [lap1])["deleted_while_present"]
    assert (d["count"], d["present"], d["gt_ids"], d["map_ids"]) == (1, 2, [3], [2])
    # Judged by the lap of the removal alone (no earlier lap given): plant 2 counts too.
    d = evaluate_map(smap, lap2)["deleted_while_present"]
    assert (d["count"], d["gt_ids"], d["map_ids"]) == (2, [2, 3], [1, 2])


def test_ids_kept_from_two_hand_built_results():
    from ltc_cli.tools.evaluate import ids_kept

    def res(gt, matches):
        return {"gt_objects": [{"id": i, "class": c, "center": [x, y, 0.5]} for i, c, x, y in gt],
                "matches": [{"gt_id": g, "map_id": m} for g, m in matches]}

    before = res([(1, "chair", 0, 0), (2, "couch", 3, 0), (3, "tv", 6, 0), (4, "chair", 9, 0),
                  (5, "potted plant", 12, 0), (7, "cup", 15, 0)],
                 [(1, 10), (2, 11), (3, 12), (5, 14), (7, 16)])
    after = res([(1, "chair", 0.05, 0),  # unchanged (5 cm), same map id: kept
                 (2, "couch", 3, 0),  # unchanged, a new map id: not kept
                 (3, "tv", 6.5, 0),  # moved: left out
                 (4, "chair", 9, 0),  # unchanged but unmapped before: no id to keep
                 (5, "potted plant", 12, 0.02),  # unchanged, unmatched now (deleted): not kept
                 (7, "bowl", 15, 0),  # another class under the same id: left out
                 (8, "chair", 18, 0)],  # new
                [(1, 10), (2, 20), (3, 12), (4, 13), (8, 21)])
    k = ids_kept(before, after)
    assert k == {"unchanged": 4, "tracked": 3, "kept": 1, "share": pytest.approx(1 / 3), "lost_gt_ids": [2, 5]}
    assert ids_kept(res([], []), after)["share"] is None
    # On real evaluation results: the same map after two laps keeps every id.
    lap1, lap2, _, maps = _three_laps()
    r1, r2 = evaluate(maps, lap1), evaluate(maps, lap2, previous_gt=lap1)
    k = ids_kept(r1, r2)
    assert (k["unchanged"], k["tracked"], k["kept"]) == (2, 2, 2)  # chair 1 and tv 3


def test_zero_over_zero_is_none():
    gt = [_obj(1, "chair", 0, 0), _obj(2, "tv", 5, 0)]
    r = evaluate([], gt)
    assert r["precision"] is None and r["recall"] == 0.0 and r["f1"] == 0.0
    assert r["duplicate_ratio"] is None and r["ghost_ratio"] is None
    assert r["recall_seen"] is None  # the ground truth does not say what was seen
    for level in r["at_iou"].values():
        assert level["precision"] is None and level["recall"] == 0.0
    r = evaluate([_obj(1, "chair", 0, 0)], [])
    assert r["precision"] == 0.0 and r["recall"] is None and r["f1"] == 0.0

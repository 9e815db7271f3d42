import numpy as np
import pytest

from ltc_cli.pipeline.association import centroid_distance, nearest_under_threshold, thresholds_for, vertex_distance
from ltc_cli.geometry.boxes import SHIFTS, Box, Boxes, box_corners
from ltc_cli.pipeline.integration import fuse_scores, integrate_box
from ltc_cli.pipeline.maintenance import non_detection_vector


def boxes(center, yaw, size, visible=None):
    vis = np.ones(8, bool) if visible is None else np.asarray(visible, bool)
    return Boxes(np.array([center], float), np.array([yaw], float), np.array([size], float), vis[None])


def test_vertex_distance_zero_for_the_same_box_renumbered_and_finds_the_shift():
    a = boxes([0, 0, 0.5], 0.0, [1, 2, 1])
    b = boxes([0, 0, 0.5], np.pi / 2, [2, 1, 1])  # the same box, vertices numbered from elsewhere
    d, shift = vertex_distance(a, b)
    assert d[0] == pytest.approx(0, abs=1e-12)
    # By hand: a's vertex 0 (-0.5, -1) is b's vertex 3, so i -> (i + 3) % 4.
    assert shift[0] == 3
    np.testing.assert_allclose(a.corners[0], b.corners[0][SHIFTS[3]], atol=1e-12)


def test_vertex_distance_of_translated_and_rotated_boxes():
    a = boxes([0, 0, 0.5], 0.2, [1, 2, 1])
    b = boxes([0.3, 0.4, 0.5], 0.2, [1, 2, 1])
    d, shift = vertex_distance(a, b)
    assert d[0] == pytest.approx(0.5) and shift[0] == 0
    # A small rotation about the common centre: every vertex moves by 2 r sin(theta / 2).
    theta = 0.1
    c = boxes([0, 0, 0.5], 0.2 + theta, [1, 2, 1])
    r = np.hypot(0.5, 1.0)
    assert vertex_distance(a, c)[0][0] == pytest.approx(2 * r * np.sin(theta / 2))


def test_vertex_distance_uses_only_pairs_visible_in_both():
    # The map box is a whole cabinet; the detection saw only its front face (vertices 0, 1, 4, 5
    # along y = -0.5), so its box is a thin slab there.
    full = boxes([0, 0, 0.5], 0.0, [1, 1, 1])
    vis = np.zeros(8, bool)
    vis[[0, 1, 4, 5]] = True
    slab = boxes([0, -0.45, 0.5], 0.0, [1, 0.1, 1], vis)
    d, _ = vertex_distance(slab, full, min_visible_pairs=3)
    assert d[0] == pytest.approx(0.0, abs=1e-12)
    # With too few shared visible pairs, all 8 vertices count: the back ones are 0.9 m apart.
    d, _ = vertex_distance(slab, full, min_visible_pairs=5)
    assert d[0] == pytest.approx((4 * 0 + 4 * 0.9) / 8)


def test_centroid_baseline_and_thresholds():
    a = boxes([0, 0, 0], 0, [1, 1, 1])
    b = Boxes(np.array([[3, 4, 0], [0, 0.1, 0]], float), np.zeros(2), np.ones((2, 3)), np.ones((2, 8), bool))
    np.testing.assert_allclose(centroid_distance(a, b), [5, 0.1])
    thr = thresholds_for(2, np.array([2, 1]), 0.4, 0.25)
    np.testing.assert_allclose(thr, [0.4, 0.25])
    assert nearest_under_threshold(np.array([0.3, 0.2]), np.array([0.4, 0.25])) == 1
    assert nearest_under_threshold(np.array([0.5, 0.3]), np.array([0.4, 0.25])) == -1


def test_eq3_fusion_by_hand():
    s = fuse_scores(np.array([0.7, 0.2, 0.1]), np.array([0.5, 0.3, 0.2]), 3)
    # (s_i + 3 s_j) = [2.2, 1.1, 0.7], sum 4.
    np.testing.assert_allclose(s, [0.55, 0.275, 0.175])


def test_eq4_non_detection_vector_by_hand():
    np.testing.assert_allclose(non_detection_vector(4, 0.6), [0.1, 0.1, 0.1, 0.1, 0.6])


def B(center, yaw, size, defined, visible=None):
    vis = np.ones(8, bool) if visible is None else np.asarray(visible, bool)
    return Box(np.array(center, float), float(yaw), np.array(size, float), vis, defined)


def test_integration_both_defined_averages_by_weight():
    obj = B([0, 0, 0.5], 0.1, [1.0, 2.0, 1.0], True)
    # The detection is the same kind of box described with a quarter turn (sizes swapped).
    det = B([1.0, 0, 0.5], 0.1 + np.pi / 2 - 0.04, [2.2, 1.2, 1.0], True)
    new = integrate_box(det, obj, w_det=1, w_obj=3, erosion=0.01, min_extent=0.05)
    np.testing.assert_allclose(new.center, [0.25, 0, 0.5])
    assert new.yaw == pytest.approx(0.1 - 0.01)  # (3 * 0.1 + 1 * 0.06) / 4
    np.testing.assert_allclose(new.size, [1.05, 2.05, 1.0])
    assert new.defined


def test_integration_partial_detection_keeps_defined_object():
    obj = B([0, 0, 0.5], 0.0, [1, 1, 1], True)
    det = B([0.3, 0, 0.5], 0.0, [0.4, 1, 1], False)
    new = integrate_box(det, obj, 1, 3, 0.01, 0.05)
    np.testing.assert_allclose(new.center, obj.center)
    np.testing.assert_allclose(new.size, obj.size)
    assert new.defined


def test_integration_defined_detection_replaces_partial_object():
    obj = B([0.3, 0, 0.5], 0.0, [0.4, 1, 1], False)
    det = B([0, 0, 0.5], 0.2, [1, 1, 1], True)
    new = integrate_box(det, obj, 1, 5, 0.01, 0.05)
    np.testing.assert_allclose(new.center, det.center)
    assert new.yaw == pytest.approx(0.2)
    np.testing.assert_allclose(new.size, det.size)
    assert new.defined


def test_integration_both_partial_encloses_and_erodes():
    vis = np.zeros(8, bool)
    obj = B([0, 0, 0.5], 0.0, [1, 1, 1], False, vis)
    det = B([0.5, 0, 0.5], 0.0, [1, 1, 1], False, vis)
    new = integrate_box(det, obj, 1, 1, erosion=0.01, min_extent=0.05)
    # Enclosing box: x in [-0.5, 1.0] -> 1.5 - 2 * 0.01; y and z stay at 1 (never below the inputs).
    np.testing.assert_allclose(new.center, [0.25, 0, 0.5], atol=1e-12)
    from ltc_cli.geometry.boxes import align_yaw

    _, size = align_yaw(0.0, new.yaw, new.size)
    np.testing.assert_allclose(size, [1.48, 1.0, 1.0], atol=1e-12)
    # The same partial view again does not shrink the box.
    again = integrate_box(new, new, 1, 1, 0.01, 0.05)
    np.testing.assert_allclose(np.sort(again.size), np.sort(new.size), atol=1e-12)
    # Corners seen in either box stay visible in the enclosing one.
    vis_obj = np.zeros(8, bool)
    vis_obj[[0, 3]] = True  # the x = -0.5 side of the object
    obj = B([0, 0, 0.5], 0.0, [1, 1, 1], False, vis_obj)
    new = integrate_box(det, obj, 1, 1, 0.01, 0.05)
    corners = box_corners(new.center, new.yaw, new.size)
    assert new.visible.sum() == 2
    assert np.all(corners[new.visible][:, 0] < -0.4)


def random_boxes(rng, m, spread=2.0):
    """m boxes crowded into a few metres: many close pairs, some inside others, random visibility."""
    center = np.c_[rng.uniform(-spread, spread, (m, 2)), rng.uniform(0.1, 1.0, m)]
    return Boxes(center, rng.uniform(-np.pi, np.pi, m), rng.uniform(0.05, 1.2, (m, 3)), rng.random((m, 8)) < 0.7)


def test_vertex_distance_is_never_below_the_centre_bound():
    # The bound behind the candidates' pre-selection (within_reach): mean corner distance >= centre
    # distance - both half diagonals, on all pairs and on the visible pairs alone.
    from ltc_cli.pipeline.association import half_diagonals

    rng = np.random.default_rng(11)
    for _ in range(30):
        b = random_boxes(rng, 50)
        for k in range(5):
            d, _ = vertex_distance(b.take(slice(k, k + 1)), b, min_visible_pairs=int(rng.integers(1, 5)))
            bound = np.linalg.norm(b.center - b.center[k], axis=1) - half_diagonals(b.size) - half_diagonals(b.size)[k]
            assert (d >= bound - 1e-12).all()


def test_duplicate_pairs_with_reach_are_those_of_every_pair():
    from ltc_cli.pipeline.deduplication import duplicate_pairs

    rng = np.random.default_rng(12)
    metric = lambda det, cands: vertex_distance(det, cands)[0]  # noqa: E731
    found = 0
    for _ in range(30):
        b = random_boxes(rng, int(rng.integers(2, 60)), spread=3.0)
        top = rng.integers(0, 3, len(b))
        args = (b, top, metric, 0.4, 0.25, 0.5, 0.7, 0.1)
        want = duplicate_pairs(*args)
        assert duplicate_pairs(*args, reach=0.05) == want
        found += len(want)
    assert found > 20  # the scenes do have duplicates


def test_paired_distances_are_those_of_one_box_against_many():
    # A metric with ``paired`` measures K pairs (a[k], b[k]) in one call: the numbers of one call
    # per detection box against its candidates (numpy may sum the 8 vertices' distances in another
    # order for another array shape: equal to the last bits), and the same shifts.
    rng = np.random.default_rng(13)
    b = random_boxes(rng, 40)
    i, j = np.triu_indices(len(b), k=1)
    for min_pairs in (1, 3, 5):
        d, shift = vertex_distance(b.take(i), b.take(j), min_visible_pairs=min_pairs)
        for a in range(len(b) - 1):
            one_d, one_shift = vertex_distance(b.take(slice(a, a + 1)), b.take(j[i == a]), min_visible_pairs=min_pairs)
            np.testing.assert_allclose(d[i == a], one_d, rtol=1e-13, atol=0)
            assert np.array_equal(shift[i == a], one_shift)
    assert np.array_equal(centroid_distance(b.take(i), b.take(j)), np.linalg.norm(b.center[i] - b.center[j], axis=1))


def test_vertex_distance_is_the_mean_corner_distance_of_the_best_shift():
    # Eq. 2 written out pair by pair, corner by corner, against the vectorised rings.
    rng = np.random.default_rng(16)
    b = random_boxes(rng, 25)
    for k in range(len(b) - 1):
        got, shift = vertex_distance(b.take(slice(k, k + 1)), b, min_visible_pairs=3)
        for m in range(len(b)):
            means = []
            for s in SHIFTS:
                pairs = [(b.corners[k][v], b.corners[m][s[v]]) for v in range(8)
                         if b.visible[k][v] and b.visible[m][s[v]]]
                if len(pairs) < 3:
                    pairs = [(b.corners[k][v], b.corners[m][s[v]]) for v in range(8)]
                means.append(np.mean([np.sqrt(((p - q) ** 2).sum()) for p, q in pairs]))
            assert got[m] == pytest.approx(min(means), rel=1e-12) and means[shift[m]] == pytest.approx(min(means))


def test_duplicate_pairs_with_a_paired_metric_are_those_of_one_call_per_box():
    from ltc_cli.pipeline.deduplication import duplicate_pairs

    rng = np.random.default_rng(14)
    metric = lambda det, cands: vertex_distance(det, cands)[0]  # noqa: E731
    calls = []

    def per_box(det, cands):
        assert len(det) == 1  # a metric without ``paired`` is called as in stage 2
        calls.append(len(cands))
        return metric(det, cands)

    found = 0
    for _ in range(30):
        m = int(rng.integers(2, 60))
        b = random_boxes(rng, m, spread=2.0)
        top, defined = rng.integers(0, 3, m), rng.random(m) < 0.5
        args = (b, top, metric, 0.4, 0.25, 0.5, 0.7, 0.1)
        kw = dict(reach=0.05, min_overlap=0.2, defined=defined, established=rng.random(m) < 0.3,
                  labels_apart=True, scores=rng.dirichlet(np.ones(4), m), min_evidence=0.1)
        want = duplicate_pairs(*args, **kw)
        for got in (duplicate_pairs(*args, **kw, paired=True), duplicate_pairs(b, top, per_box, *args[3:], **kw)):
            assert [p[1:] for p in got] == [p[1:] for p in want]
            np.testing.assert_allclose([p[0] for p in got], [p[0] for p in want], rtol=1e-13, atol=0)
        found += len(want)
    assert found > 50 and len(calls) > 300  # scenes with duplicates, measured box by box


def test_mapper_decides_the_same_with_and_without_the_candidate_bound():
    # Frames of 30 crowded boxes, detections jittered: the maps made with the vertex metric (which
    # declares center_bound, so candidates are pre-selected) and with the same metric not declaring
    # it (every candidate compared) are identical, column for column.
    from ltc_cli import plugins
    from ltc_cli.config import defaults
    from ltc_cli.map.model import SemanticMap
    from ltc_cli.pipeline.mapper import Mapper
    from tests.scene import INTR, T_world_camera, render

    class Unbounded:  # nor ``paired``: the de-duplication measures its pairs one box at a time
        center_bound = False

        def __init__(self, inner):
            self.inner = inner

        def distance(self, det, cands):
            return self.inner.distance(det, cands)

    cfg = defaults()
    rng = np.random.default_rng(5)
    objs = [(x, x + 0.3, y, y + w, z, z + h) for x, y, z, w, h in zip(rng.uniform(2.5, 3.5, 30), rng.uniform(-1.5, 1.3, 30),
                                                                     rng.uniform(0, 1.5, 30), rng.uniform(0.1, 0.5, 30),
                                                                     rng.uniform(0.1, 0.6, 30))]
    maps = []
    for bounded in (True, False):
        metric = plugins.get("metrics", "vertex").factory(cfg["association"])
        smap = SemanticMap.new(["a", "b", "c"])
        mapper = Mapper(smap, cfg, metric if bounded else Unbounded(metric),
                        plugins.get("policies", "non-detection").factory(cfg["maintenance"]))
        frame_rng = np.random.default_rng(6)
        for i in range(12):
            cam_y = 0.1 * np.sin(i)
            depth, masks = render(objs, wall_x=4.0, cam_y=cam_y)
            depth = depth + frame_rng.normal(0, 0.01, depth.shape).astype(np.float32)
            keep = [m for m in masks if m.sum() > 50]
            vecs = [np.roll([0.7, 0.1, 0.1, 0.1], int(frame_rng.integers(0, 3))) for _ in keep]
            mapper.process_frame(i, str(i), keep, vecs, depth, T_world_camera(cam_y=cam_y), INTR, (0.3, 6.0))
        maps.append(smap)
    a, b = maps
    assert a.objects.n == b.objects.n > 10
    for name, col in a.objects.cols.items():
        assert np.array_equal(col[: a.objects.n], b.objects.cols[name][: b.objects.n]), name
    assert [(e.kind, e.object_id, e.other_id) for e in a.events] == [(e.kind, e.object_id, e.other_id) for e in b.events]


def test_pairwise_containment_is_the_share_of_volume_inside_by_shapely():
    # A second implementation: shapely's footprint intersection times the z overlap, over the
    # first box's volume; pairs apart in height or in their footprints' extents give 0.
    from shapely.geometry import Polygon

    from ltc_cli.pipeline.association import pairwise_containment

    rng = np.random.default_rng(15)
    for _ in range(5):
        b = random_boxes(rng, 30, spread=1.5)
        got = pairwise_containment(b)
        feet = [Polygon(c[:4, :2]) for c in b.corners]
        z0, z1 = b.center[:, 2] - b.size[:, 2] / 2, b.center[:, 2] + b.size[:, 2] / 2
        want = np.array([[feet[i].intersection(feet[j]).area * max(0.0, min(z1[i], z1[j]) - max(z0[i], z0[j]))
                          / np.prod(b.size[i]) for j in range(len(b))] for i in range(len(b))])
        np.fill_diagonal(want, 1.0)
        np.testing.assert_allclose(got, want, atol=1e-9)
        assert 0 < (want[~np.eye(len(b), dtype=bool)] > 0).mean() < 0.9  # some pairs overlap, some do not

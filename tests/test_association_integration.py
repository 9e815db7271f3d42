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

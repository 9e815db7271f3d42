import numpy as np
import pytest

from ltc_cli.config import defaults
from ltc_cli.geometry.boxes import align_yaw, box_corners
from ltc_cli.geometry.camera import invert_pose
from ltc_cli.pipeline.clustering import dbscan_labels, largest_clusters
from ltc_cli.pipeline.modeling import (
    defined_flags,
    model_detections,
    thin_mask,
    valid_depth_share,
    vertex_visibility,
)
from tests.scene import INTR, T_world_camera, face_rect, render


def chair_points(rng):
    """A chair-like point set: a seat, four legs and a back, 0.5 x 0.5 x 0.9 m, axis-aligned at
    the origin; points 1 cm apart on average."""
    parts = [
        rng.uniform([-0.25, -0.25, 0.43], [0.25, 0.25, 0.47], (400, 3)),  # seat
        rng.uniform([0.21, -0.25, 0.47], [0.25, 0.25, 0.9], (300, 3)),  # back
    ]
    for x, y in [(-0.23, -0.23), (-0.23, 0.23), (0.23, -0.23), (0.23, 0.23)]:
        parts.append(rng.uniform([x - 0.02, y - 0.02, 0.0], [x + 0.02, y + 0.02, 0.43], (60, 3)))
    return np.vstack(parts)


def test_thinning_drops_a_boundary_band_bounded_by_max_iterations():
    mask = np.zeros((100, 200), bool)
    mask[20:80, 50:150] = True  # 60 x 100 px
    thin = thin_mask(mask, max_iterations=5, fraction=0.05)  # k = min(5, 0.05 * 60) = 3
    assert thin.sum() == (60 - 6) * (100 - 6)
    assert thin[23, 53] and not thin[22, 53]
    thin = thin_mask(mask, max_iterations=2, fraction=0.5)  # k = 2
    assert thin.sum() == 56 * 96
    small = np.zeros((50, 50), bool)
    small[10:15, 10:15] = True  # too small to thin: 0.05 * 5 < 1
    assert (thin_mask(small, 5, 0.05) == small).all()


@pytest.mark.parametrize("method", ["grid", "voxel", "dbscan"])
def test_largest_cluster_drops_bleed_and_noise(method):
    rng = np.random.default_rng(0)
    chair = chair_points(rng)
    bleed = rng.uniform([0.9, -0.4, 0.2], [0.95, 0.4, 1.0], (250, 3))  # a patch of wall behind it
    noise = rng.uniform([-2, -2, 0], [2, 2, 2], (15, 3))  # flying pixels
    noise = noise[np.min(np.linalg.norm(noise[:, None] - chair[None], axis=-1), axis=1) > 0.3]
    pts = np.vstack([chair, bleed, noise])
    clusters = largest_clusters(pts, np.zeros(len(pts), int), eps=0.15, min_samples=20, method=method)
    kept = clusters[0]
    assert set(kept.tolist()) == set(range(len(chair)))


def test_voxel_components_match_dbscan_on_the_chair():
    rng = np.random.default_rng(3)
    chair = chair_points(rng)
    other = chair + [2.0, 0, 0]
    pts = np.vstack([chair, other])
    group = np.r_[np.zeros(len(chair), int), np.ones(len(other), int)]
    vox = largest_clusters(pts, group, 0.15, 20, "voxel")
    exact = largest_clusters(pts, group, 0.15, 20, "dbscan")
    for a, b in zip(vox, exact):
        assert set(a.tolist()) == set(b.tolist())


@pytest.mark.parametrize("seed", [3, 4, 5])
def test_grid_clusters_match_exact_dbscan(seed):
    """Two chairs 0.6 m apart, a wall patch behind one, joined to it by a sparse line of flying
    pixels: exact DBSCAN (min_samples 20) keeps each chair apart from the wall; so must the grid."""
    rng = np.random.default_rng(seed)
    chair = chair_points(rng)
    other = chair_points(rng) + [0, 1.1, 0]
    wall = rng.uniform([0.9, -0.5, 0.0], [0.92, 0.5, 1.2], (600, 3))
    bridge = np.linspace([0.27, 0, 0.7], [0.9, 0, 0.7], 12) + rng.normal(0, 0.005, (12, 3))
    pts = np.vstack([chair, other, wall, bridge])
    group = np.r_[np.zeros(len(chair), int), np.ones(len(other), int), np.zeros(len(wall) + len(bridge), int)]
    exact = largest_clusters(pts, group, 0.15, 20, "dbscan")
    grid = largest_clusters(pts, group, 0.15, 20, "grid")
    for a, b in zip(exact, grid):
        a, b = set(a.tolist()), set(b.tolist())
        assert len(a ^ b) <= 0.02 * len(a)  # the same points but for a few borders
    # Group 0's largest cluster is the chair alone, without the wall behind the bridge.
    wall_idx = set(range(2 * len(chair), 2 * len(chair) + len(wall)))
    assert set(range(len(chair))) <= set(grid[0].tolist()) and not wall_idx & set(grid[0].tolist())
    # Voxel components (min_samples 1) follow the bridge and join chair and wall.
    vox = largest_clusters(pts, group, 0.15, 20, "voxel")
    assert wall_idx <= set(vox[0].tolist())


def test_dbscan_labels_by_hand():
    pts = np.array([[0, 0, 0], [0.1, 0, 0], [0.2, 0, 0], [5, 5, 5], [0.3, 0, 0]], dtype=float)
    labels = dbscan_labels(pts, eps=0.15, min_samples=3)
    # 0.1 and 0.2 have 3 points within eps (themselves included): core; 0 and 0.3 are border points.
    assert labels[3] == -1
    assert len(set(labels[[0, 1, 2, 4]])) == 1 and labels[0] >= 0


def test_visibility_of_a_box_half_out_of_the_image():
    T_wc = T_world_camera()
    depth = np.full((INTR.height, INTR.width), 6.0, np.float32)
    # Box 2 m ahead, spanning y in [-0.5, 2.5]: its left side (large +y) is outside the image
    # (at 2 m the half-width of the view is 2 * 319.5 / 500 = 1.28 m).
    corners = box_corners([2.0, 1.0, 0.8], 0.0, [0.4, 3.0, 0.6])
    vis = vertex_visibility(corners[None], invert_pose(T_wc), depth, INTR, border=10, occlusion_tolerance=0.2)[0]
    y = corners[:, 1]
    np.testing.assert_array_equal(vis, y < 0)
    assert not defined_flags(vis[None])[0]  # the y extent was not observed


def test_visibility_behind_a_nearer_surface():
    T_wc = T_world_camera()
    corners = box_corners([3.0, 0.0, 0.8], 0.0, [0.4, 0.6, 0.6])
    depth = np.full((INTR.height, INTR.width), 6.0, np.float32)
    vis = vertex_visibility(corners[None], invert_pose(T_wc), depth, INTR, 10, 0.2)[0]
    assert vis.all() and defined_flags(vis[None])[0]
    # A wall at 2 m covering the right half of the image hides the vertices with y < 0.
    depth[:, 320:] = 2.0
    vis = vertex_visibility(corners[None], invert_pose(T_wc), depth, INTR, 10, 0.2)[0]
    np.testing.assert_array_equal(vis, corners[:, 1] > 0)
    # A surface only 0.1 m nearer than the vertices is within the tolerance: still visible.
    depth[:, :] = 2.7
    vis = vertex_visibility(corners[None], invert_pose(T_wc), depth, INTR, 10, 0.2)[0]
    np.testing.assert_array_equal(vis, corners[:, 0] < 2.9)


def test_defined_needs_each_axis():
    vis = np.zeros(8, bool)
    vis[[0, 1]] = True  # an x edge
    assert not defined_flags(vis)
    vis[[2]] = True  # + a y edge (1-2)
    assert not defined_flags(vis)
    vis[[5]] = True  # + a z edge (1-5)
    assert defined_flags(vis)


def test_model_detections_on_an_analytic_scene():
    p = defaults()["modeling"]
    # A cabinet 0.6 (y) x 0.8 (z) whose front face is 2 m ahead; the wall is 4 m ahead.
    box = (2.0, 2.4, -0.3, 0.3, 0.2, 1.0)
    depth, masks = render([box], wall_x=4.0)
    # The detector's mask bleeds 6 px onto the wall on every side.
    u0, u1, v0, v1 = face_rect(-0.3, 0.3, 0.2, 1.0, 2.0)
    mask = np.zeros_like(masks[0])
    mask[v0 - 6 : v1 + 6, u0 - 6 : u1 + 6] = True
    out = model_detections([mask], depth, INTR, T_world_camera(), p, (0.3, 6.0))
    assert len(out.source) == 1
    c, s = out.boxes.center[0], out.boxes.size[0]
    # Only the front face is seen: its thickness is padded to min_extent about the face.
    _, size = align_yaw(0.0, out.boxes.yaw[0], s)
    assert c[0] == pytest.approx(2.0, abs=1e-4)
    assert size[0] == pytest.approx(p["min_extent"])
    # The face: 0.6 wide, 0.8 high; thinning and subsampling lose at most a few cm.
    assert size[1] == pytest.approx(0.6, abs=0.05)
    assert size[2] == pytest.approx(0.8, abs=0.05)
    assert c[2] == pytest.approx(0.6, abs=0.03)
    assert abs(c[1]) < 0.03


def test_thinning_is_scipy_minimum_filter_pixel_for_pixel():
    # The erosion is OpenCV's (speed, issue 11); scipy.ndimage's minimum filter, mode "nearest",
    # on the same crop is the reference, on random blobs, at the image borders too.
    from scipy import ndimage

    from ltc_cli.pipeline.modeling import thin_iterations

    rng = np.random.default_rng(7)
    for trial in range(60):
        h, w = rng.integers(20, 90, 2)
        mask = ndimage.binary_dilation(rng.random((h, w)) < 0.03, iterations=int(rng.integers(1, 6)))
        if trial % 3 == 0:
            mask[: rng.integers(1, 10)] = True  # cut by the top border
        max_it, frac = int(rng.integers(1, 8)), float(rng.uniform(0.02, 0.5))
        rows, cols = np.flatnonzero(mask.any(1)), np.flatnonzero(mask.any(0))
        r0, r1, c0, c1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
        k = thin_iterations(r1 - r0, c1 - c0, max_it, frac)
        R0, R1, C0, C1 = max(r0 - k, 0), min(r1 + k, h), max(c0 - k, 0), min(c1 + k, w)
        want = np.zeros_like(mask)
        crop = mask[R0:R1, C0:C1]
        want[R0:R1, C0:C1] = ndimage.minimum_filter(crop, size=2 * k + 1, mode="nearest") if k > 0 else crop
        assert (thin_mask(mask, max_it, frac) == want).all(), trial


def test_valid_depth_share_by_hand():
    depth = np.array([[0.0, 1.0, 2.0, 0.0],
                      [1.0, 0.0, 7.0, 1.5],
                      [0.2, 1.0, 1.0, 0.0]])
    crop = np.array([[True, True, True],
                     [True, False, True]])  # 5 pixels, at rows 1-2, columns 1-3
    # Its depths: 0 (none), 7 (beyond max), 1.5, 1.0, 0 (none): 1.5 and 1.0 are in (0.3, 6.0).
    assert valid_depth_share(crop, 1, 1, depth, 0.3, 6.0) == pytest.approx(2 / 5)
    assert valid_depth_share(np.zeros((2, 2), bool), 0, 0, depth, 0.3, 6.0) == 0.0


def test_min_depth_share_drops_a_dark_screen():
    p = dict(defaults()["modeling"])
    p["min_mask_explained"] = None  # min_depth_share alone (both: tests/test_mask_explained.py)
    # A monitor 0.6 (y) x 0.8 (z) 2 m ahead whose dark screen gives depth only on a central
    # strip a tenth of its width: after thinning about 10-12 % of the mask has depth.
    depth, _ = render([(2.0, 2.05, -0.3, 0.3, 0.2, 1.0)], wall_x=4.0)
    u0, u1, v0, v1 = face_rect(-0.3, 0.3, 0.2, 1.0, 2.0)
    mask = np.zeros(depth.shape, bool)
    mask[v0:v1, u0:u1] = True
    strip = (u1 - u0) // 10
    mid = (u0 + u1) // 2
    hole = mask.copy()
    hole[:, mid - strip // 2 : mid - strip // 2 + strip] = False
    depth[hole] = 0.0
    # Without the setting the strip's points make a box (the paper's behaviour).
    p["min_depth_share"] = None
    assert len(model_detections([mask], depth, INTR, T_world_camera(), p, (0.3, 6.0)).source) == 1
    p["min_depth_share"] = 0.05
    assert len(model_detections([mask], depth, INTR, T_world_camera(), p, (0.3, 6.0)).source) == 1
    p["min_depth_share"] = 0.2
    assert len(model_detections([mask], depth, INTR, T_world_camera(), p, (0.3, 6.0)).source) == 0
    # The default (0.2) drops it too, and keeps the same screen when its depth covers a strip
    # four tenths of its width (about 35-40 % of the thinned mask).
    p["min_depth_share"] = defaults()["modeling"]["min_depth_share"]
    assert len(model_detections([mask], depth, INTR, T_world_camera(), p, (0.3, 6.0)).source) == 0
    depth, _ = render([(2.0, 2.05, -0.3, 0.3, 0.2, 1.0)], wall_x=4.0)
    hole = mask.copy()
    hole[:, mid - 2 * strip : mid + 2 * strip] = False
    depth[hole] = 0.0
    assert len(model_detections([mask], depth, INTR, T_world_camera(), p, (0.3, 6.0)).source) == 1


@pytest.mark.parametrize("method", ["grid", "dbscan"])
def test_pixel_weights_count_the_pixels_a_subsampled_point_stands_for(method):
    """A 1.0 x 0.6 m plane sampled every 0.1 m, as a stride-3 subsample of a mask whose pixels lie
    3.3 cm apart. Each point has 9 points within eps 0.15 (itself, 4 at 0.1 m, 4 at 0.141 m) or
    fewer at the edges: counted once, under min_samples 20 everywhere, so no cluster; counted for
    its 3^2 = 9 pixels, at least 4 x 9 = 36 at a corner, every point is core: one cluster of all 77
    (exact DBSCAN; the grid's cells, a coarser neighbourhood, may leave out a few corner points)."""
    xs, ys = np.meshgrid(np.arange(11) * 0.1, np.arange(7) * 0.1)
    pts = np.c_[xs.ravel(), ys.ravel(), np.zeros(xs.size)]
    group = np.zeros(len(pts), int)
    assert largest_clusters(pts, group, 0.15, 20, method)[0] is None
    weights = np.full(len(pts), 9.0)
    kept = largest_clusters(pts, group, 0.15, 20, method, weights=weights)[0]
    if method == "dbscan":
        assert sorted(kept.tolist()) == list(range(77))
    else:
        assert len(kept) >= 0.95 * 77
    # The same plane at its pixels' spacing (every 0.0333 m), counted once, is one cluster too:
    # the weights give the subsample the full mask's clustering.
    xf, yf = np.meshgrid(np.arange(31) / 30, np.arange(19) / 30)
    full = np.c_[xf.ravel(), yf.ravel(), np.zeros(xf.size)]
    assert len(largest_clusters(full, np.zeros(len(full), int), 0.15, 20, method)[0]) == len(full)


def test_pixel_weights_reach_the_clustering_through_the_settings():
    """model_detections passes stride^2 weights only when modeling.pixel_weights is true: the
    same sparse set of points is dropped without it and kept with it."""
    p = dict(defaults()["modeling"])
    assert p["pixel_weights"] is False
    # A fronto-parallel face 2 m ahead, 0.6 x 0.4 m: about 150 x 100 px, so max_points 40
    # samples it with stride 20 (8 cm between points at 2 m): under 20 points within eps each.
    depth, _ = render([(2.0, 2.05, -0.3, 0.3, 0.6, 1.0)], wall_x=4.0)
    u0, u1, v0, v1 = face_rect(-0.3, 0.3, 0.6, 1.0, 2.0)
    mask = np.zeros(depth.shape, bool)
    mask[v0:v1, u0:u1] = True
    p.update(max_points=40, min_samples=20, thin_max_iterations=0, clustering="dbscan")
    assert len(model_detections([mask], depth, INTR, T_world_camera(), p, (0.3, 6.0)).source) == 0
    p["pixel_weights"] = True
    assert len(model_detections([mask], depth, INTR, T_world_camera(), p, (0.3, 6.0)).source) == 1


def test_pixel_weights_by_class_weigh_those_classes_only():
    """modeling.pixel_weights as a class list: a detection of a listed class is clustered as with
    pixel_weights true, one of another class as with false (the sparse face of the test above:
    kept with weights, dropped without)."""
    from ltc_cli.pipeline.frame_modeling import ClassFlags, model_frame

    cfg = defaults()
    cfg["modeling"].update(max_points=40, min_samples=20, thin_max_iterations=0, clustering="dbscan")
    cfg["modeling"]["pixel_weights"] = ["bed"]
    classes = ["bed", "chair"]
    flags = ClassFlags.from_settings(classes, cfg)
    assert flags.weighted.tolist() == [True, False, False]
    depth, _ = render([(2.0, 2.05, -0.3, 0.3, 0.6, 1.0)], wall_x=4.0)
    u0, u1, v0, v1 = face_rect(-0.3, 0.3, 0.6, 1.0, 2.0)
    mask = np.zeros(depth.shape, bool)
    mask[v0:v1, u0:u1] = True
    bed, chair = np.array([0.9, 0.05, 0.05]), np.array([0.05, 0.9, 0.05])
    out = model_frame([mask, mask], [bed, chair], depth, T_world_camera(), INTR, (0.3, 6.0), cfg, flags)
    assert out.modeled.source.tolist() == [0]  # the bed's box only
    cfg["modeling"]["pixel_weights"] = False
    assert ClassFlags.from_settings(classes, cfg).weighted is None

import numpy as np
import pytest

from ltc_cli.geometry.boxes import Boxes, align_yaw, box_corners, fit_box, min_area_rect, wrap_yaw
from ltc_cli.geometry.camera import backproject, is_rotation, pose_matrix, quat_to_rot, rotation_between
from ltc_cli.types import Intrinsics

INTR = Intrinsics(640, 480, 500.0, 400.0, 320.0, 240.0)


def test_backprojection_of_known_pixels():
    # Eq. 1 by hand: X = Z (u - cx) / fx, Y = Z (v - cy) / fy.
    u = np.array([320.0, 820.0, 70.0])
    v = np.array([240.0, 240.0, 640.0])
    z = np.array([1.0, 2.0, 4.0])
    pts = backproject(u, v, z, INTR)
    np.testing.assert_allclose(pts, [[0, 0, 1], [2.0, 0, 2], [-2.0, 4.0, 4]])


def test_corners_order_and_yaw_wrap():
    c = box_corners([0, 0, 1], 0.0, [2, 1, 2])
    np.testing.assert_allclose(c[0], [-1, -0.5, 0])
    np.testing.assert_allclose(c[1], [1, -0.5, 0])
    np.testing.assert_allclose(c[2], [1, 0.5, 0])
    np.testing.assert_allclose(c[3], [-1, 0.5, 0])
    np.testing.assert_allclose(c[4:, 2], 2)
    # Counter-clockwise seen from above: positive signed area (shoelace).
    x, y = c[:4, 0], c[:4, 1]
    assert 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) == pytest.approx(2.0)
    assert wrap_yaw(np.pi / 2) == pytest.approx(-np.pi / 2)
    assert wrap_yaw(-np.pi / 2) == pytest.approx(-np.pi / 2)
    assert wrap_yaw(3.0) == pytest.approx(3.0 - np.pi)


def test_min_area_rect_of_rotated_rectangle():
    rng = np.random.default_rng(1)
    yaw, (sx, sy), centre = np.deg2rad(30), (2.0, 0.8), np.array([1.0, -2.0])
    # Points filling the rectangle, plus its 4 corners so the extent is exact.
    local = rng.uniform(-0.5, 0.5, (500, 2)) * [sx, sy]
    local = np.vstack([local, [[-sx / 2, -sy / 2], [sx / 2, -sy / 2], [sx / 2, sy / 2], [-sx / 2, sy / 2]]])
    R = np.array([[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]])
    xy = local @ R.T + centre
    c, got_yaw, (gx, gy) = min_area_rect(xy)
    np.testing.assert_allclose(c, centre, atol=1e-9)
    # Same rectangle: either (30 deg, 2 x 0.8) or (-60 deg, 0.8 x 2).
    a_yaw, a_size = align_yaw(yaw, got_yaw, [gx, gy, 0])
    assert a_yaw == pytest.approx(yaw)
    np.testing.assert_allclose(a_size[:2], [sx, sy], atol=1e-9)
    assert -np.pi / 2 <= got_yaw < np.pi / 2


def test_fit_box_height_from_z_range():
    pts = np.array([[0, 0, 0.2], [1, 0, 0.5], [1, 2, 1.0], [0, 2, 0.7]], dtype=float)
    center, yaw, size = fit_box(pts)
    assert center[2] == pytest.approx(0.6)
    assert size[2] == pytest.approx(0.8)
    assert sorted(size[:2]) == pytest.approx([1, 2])


def test_align_yaw_swaps_sizes_for_quarter_turns():
    yaw, size = align_yaw(0.1, 0.1 + np.pi / 2, [1.0, 3.0, 2.0])
    assert yaw == pytest.approx(0.1)
    np.testing.assert_allclose(size, [3.0, 1.0, 2.0])
    # The same physical box either way.
    np.testing.assert_allclose(
        np.sort(box_corners([0, 0, 0], 0.1 + np.pi / 2, [1, 3, 2]).round(9), axis=0),
        np.sort(box_corners([0, 0, 0], yaw, size).round(9), axis=0),
    )


def test_quaternions_and_rotations():
    R = quat_to_rot([0, 0, np.sin(np.pi / 4), np.cos(np.pi / 4)])  # 90 deg about z
    np.testing.assert_allclose(R @ [1, 0, 0], [0, 1, 0], atol=1e-12)
    assert is_rotation(R)
    assert not is_rotation(2 * R)
    assert not is_rotation(np.diag([1, 1, -1.0]))
    T = pose_matrix([1, 2, 3], [0, 0, 0, 1])
    np.testing.assert_allclose(T[:3, 3], [1, 2, 3])
    up = np.array([-0.08, -0.95, -0.30])
    Rz = rotation_between(up, [0, 0, 1])
    np.testing.assert_allclose(Rz @ (up / np.linalg.norm(up)), [0, 0, 1], atol=1e-12)
    assert is_rotation(Rz)
    np.testing.assert_allclose(rotation_between([0, 0, -1], [0, 0, 1]) @ [0, 0, -1], [0, 0, 1], atol=1e-12)


def test_boxes_take_and_corners_shape():
    b = Boxes(np.zeros((3, 3)), np.zeros(3), np.ones((3, 3)), np.zeros((3, 8), bool))
    assert b.corners.shape == (3, 8, 3)
    assert len(b.take([0, 2])) == 2


def test_box_corners_bit_for_bit_those_of_rotating_each_signed_half_size():
    # The reference is the plain formula on (..., 8, 3) arrays, which box_corners computed before
    # it was made faster (issue 11): the exports must not change by one bit, signed zeros included.
    from ltc_cli.geometry.boxes import CORNER_SIGNS

    def reference(center, yaw, size):
        center, size, yaw = (np.asarray(a, dtype=np.float64) for a in (center, size, yaw))
        local = CORNER_SIGNS * (size[..., None, :] / 2.0)
        c, s = np.cos(yaw)[..., None], np.sin(yaw)[..., None]
        x = c * local[..., 0] - s * local[..., 1]
        y = s * local[..., 0] + c * local[..., 1]
        return np.stack([x, y, local[..., 2]], axis=-1) + center[..., None, :]

    rng = np.random.default_rng(4)
    n = 20000
    center = rng.normal(0, 50, (n, 3))
    yaw = rng.uniform(-4, 4, n)
    size = rng.uniform(0, 3, (n, 3))
    yaw[:2000] = rng.choice([0.0, -0.0, np.pi / 2, -np.pi / 2, np.pi, np.pi / 4], 2000)
    center[2000:4000] = rng.choice([0.0, -0.0, 1.0], (2000, 3))
    size[4000:6000] = rng.choice([0.0, 1.0, 2.0], (2000, 3))
    got, want = box_corners(center, yaw, size), reference(center, yaw, size)
    assert got.shape == want.shape and got.tobytes() == want.tobytes()
    for args in [([0, 0, 1], 0.0, [2, 1, 2]), ([-0.0, 0.0, -0.0], -0.0, [0, 0, 0]), (center[:5], 0.3, [1, 2, 3])]:
        assert box_corners(*args).tobytes() == reference(*args).tobytes()

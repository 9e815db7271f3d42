"""Rotations through scipy (ltc_cli/geometry/camera.py, TUM pose interpolation), checked against
closed forms: Rodrigues' formula for the smallest rotation between two directions, and rotations
about z for slerp."""

import numpy as np
import pytest

from ltc_cli.geometry.boxes import rot_z
from ltc_cli.geometry.camera import is_rotation, quat_to_rot, rotation_between
from ltc_plugins.readers import TumReader
from tests.test_readers import make_tum, quat_z


def rodrigues(axis, angle):
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def test_quat_to_rot_is_the_rotation_about_the_quaternions_axis():
    rng = np.random.default_rng(3)
    for _ in range(20):
        axis, angle = rng.normal(size=3), rng.uniform(0, np.pi)
        k = axis / np.linalg.norm(axis)
        q = [*(np.sin(angle / 2) * k), np.cos(angle / 2)]
        np.testing.assert_allclose(quat_to_rot(q), rodrigues(axis, angle), atol=1e-12)


def test_rotation_between_is_the_smallest_rotation():
    rng = np.random.default_rng(4)
    for _ in range(50):
        a, b = rng.normal(size=3), rng.normal(size=3)
        ua, ub = a / np.linalg.norm(a), b / np.linalg.norm(b)
        # About a x b by the angle between them (Rodrigues): the unique smallest rotation.
        want = rodrigues(np.cross(ua, ub), np.arccos(np.clip(ua @ ub, -1, 1)))
        got = rotation_between(a, b)
        np.testing.assert_allclose(got, want, atol=1e-12)
        np.testing.assert_allclose(got @ ua, ub, atol=1e-12)
    np.testing.assert_allclose(rotation_between([0, 0, 2], [0, 0, 1]), np.eye(3), atol=1e-15)


@pytest.mark.parametrize("a", [[0, 0, -1], [0, 0, 1], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [1, 2, 3]])
def test_rotation_between_opposite_directions_is_a_fixed_half_turn(a):
    a = np.asarray(a, float) / np.linalg.norm(a)
    R = rotation_between(a, -a)
    assert is_rotation(R)
    np.testing.assert_allclose(R @ a, -a, atol=1e-12)
    # A half turn about an axis normal to a: a x (1, 0, 0), or a x (0, 1, 0) when a is along x.
    axis = np.cross(a, [1.0, 0, 0]) if abs(a[0]) < 1 - 1e-9 else np.cross(a, [0, 1.0, 0])
    np.testing.assert_allclose(R, rodrigues(axis, np.pi), atol=1e-12)


def test_tum_slerp_is_exact_for_small_turns(tmp_path):
    # 0.04 rad between two trajectory stamps 20 ms apart; the frame at 1.000 s is a quarter of the way.
    theta = 0.04
    gt = "\n".join([
        "0.995 0 0 0 " + " ".join(map(str, quat_z(0.0))),
        "1.015 4 0 0 " + " ".join(map(str, quat_z(theta))),
        "1.030 4 0 0 " + " ".join(map(str, quat_z(theta))),
        "1.040 4 0 0 " + " ".join(map(str, quat_z(theta))),
    ])  # fmt: skip
    rec = TumReader().open(make_tum(tmp_path, gt_override=gt), {})
    T = rec.frames[0].load().T_world_camera
    np.testing.assert_allclose(T[:3, :3], rot_z(0.25 * theta), atol=1e-12)
    np.testing.assert_allclose(T[:3, 3], [1.0, 0.0, 0.0], atol=1e-12)

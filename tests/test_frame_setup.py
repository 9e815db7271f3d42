"""Up-axis estimation (ltc_cli.ingest.frame_setup): synthetic worlds that are not z-up, and the real dining room."""

from __future__ import annotations


import numpy as np
import pytest

from ltc_cli.geometry.camera import is_rotation, pose_matrix
from ltc_cli.types import Intrinsics
from ltc_cli.ingest.frame_setup import cameras_up, estimate_up, estimate_up_from_frames, up_rotation
from tests.shared_data import SHARED

DINING = SHARED / "data" / "dining-room"
INTR = Intrinsics(width=80, height=60, fx=60.0, fy=60.0, cx=39.5, cy=29.5)


def angle_deg(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    c = a @ b / np.linalg.norm(a) / np.linalg.norm(b)
    return float(np.degrees(np.arccos(np.clip(c, -1, 1))))


def camera_pose(position, yaw, pitch_down, down=(0.0, 1.0, 0.0), roll=0.0) -> np.ndarray:
    """T_world_camera (4, 4) of an OpenCV camera in a world whose "down" is ``down``.

    The camera looks along the horizontal direction ``yaw`` (about the down axis), pitched down by
    ``pitch_down`` and rolled by ``roll`` about its optical axis (radians).
    """
    d = np.asarray(down, float)
    d /= np.linalg.norm(d)
    # Two horizontal directions of this world.
    h1 = np.cross(d, [0.0, 0.0, 1.0]) if abs(d[2]) < 0.9 else np.cross(d, [1.0, 0.0, 0.0])
    h1 /= np.linalg.norm(h1)
    h2 = np.cross(d, h1)
    horiz = np.cos(yaw) * h2 + np.sin(yaw) * h1
    z = np.cos(pitch_down) * horiz + np.sin(pitch_down) * d
    x = np.cross(d, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    c, s = np.cos(roll), np.sin(roll)
    x, y = c * x + s * y, -s * x + c * y
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2] = x, y, z
    T[:3, 3] = position
    return T


def render_depth(T_world_camera, planes, intr=INTR) -> np.ndarray:
    """Ray-cast a depth image (H, W) against planes [(n (3,), d, bounds or None)], n . p = d."""
    v, u = np.mgrid[0 : intr.height, 0 : intr.width].astype(float)
    rays_cam = np.stack([(u - intr.cx) / intr.fx, (v - intr.cy) / intr.fy, np.ones_like(u)], -1)
    R, o = T_world_camera[:3, :3], T_world_camera[:3, 3]
    rays = rays_cam @ R.T  # world directions with unit z in the camera: hit distance t = depth
    depth = np.full(u.shape, np.inf)
    for n, d, inside in planes:
        n = np.asarray(n, float)
        denom = rays @ n
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (d - o @ n) / denom
        ok = np.isfinite(t) & (t > 0.05)
        if inside is not None:
            hit = o + rays * t[..., None]
            ok &= inside(hit)
        depth = np.where(ok & (t < depth), t, depth)
    depth[~np.isfinite(depth)] = 0.0
    return depth.astype(np.float32)


def y_down_room():
    """A room whose up is -y: floor at y = +1.2, a table top at y = +0.45 (in view), four walls."""
    planes = [
        ((0.0, 1.0, 0.0), 1.2, None),  # floor: y = 1.2
        ((1.0, 0.0, 0.0), 3.0, None),  # walls x = +-3, z = +-3
        ((1.0, 0.0, 0.0), -3.0, None),
        ((0.0, 0.0, 1.0), 3.0, None),
        ((0.0, 0.0, 1.0), -3.0, None),
        (
            (0.0, 1.0, 0.0),
            0.45,
            lambda p: (np.abs(p[..., 0] - 0.5) < 0.8) & (np.abs(p[..., 2] + 1.5) < 0.6),
        ),
    ]
    rng = np.random.default_rng(3)
    poses = [
        camera_pose(
            [rng.uniform(-1, 1), 0.0, rng.uniform(-1, 1)],
            # Facing one way (as a hand-held sweep of a room does): the pitch biases the guess.
            yaw=rng.uniform(-0.6, 0.6),
            pitch_down=np.radians(rng.uniform(15, 30)),
            roll=np.radians(rng.uniform(-5, 5)),
        )
        for k in range(8)
    ]
    return planes, np.stack(poses)


def test_camera_guess_is_mean_minus_y():
    T = np.stack([camera_pose([0, 0, 0], yaw=a, pitch_down=0.0) for a in (0.0, 1.0, 2.0)])
    assert angle_deg(cameras_up(T), [0, -1, 0]) < 1e-6
    # Pitched-down cameras: the guess leans forward by the pitch, which the floor then corrects.
    T = camera_pose([0, 0, 0], yaw=0.0, pitch_down=np.radians(20))[None]
    assert angle_deg(cameras_up(T), [0, -1, 0]) == pytest.approx(20.0, abs=1e-6)


def test_y_down_world_up_found_from_floor():
    planes, poses = y_down_room()
    samples = [(render_depth(T, planes), T) for T in poses]
    guess = cameras_up(poses)
    up = estimate_up(poses, samples, INTR)
    assert angle_deg(guess, [0, -1, 0]) > 10  # the cameras alone are off...
    assert angle_deg(up, [0, -1, 0]) < 3  # ...the floor is not
    assert np.linalg.norm(up) == pytest.approx(1.0)
    # Deterministic: the same input gives the same answer.
    np.testing.assert_array_equal(up, estimate_up(poses, samples, INTR))


def test_prefers_lowest_plane_over_a_larger_tilted_one():
    """A big surface tilted by 8 degrees above a smaller flat floor: the floor wins."""
    tilt = np.radians(8)
    n_tilted = np.array([np.sin(tilt), 1.0 * np.cos(tilt), 0.0])  # "down"-facing normal, y-down world
    planes = [
        ((0.0, 1.0, 0.0), 1.2, None),
        (
            tuple(n_tilted),
            0.3,
            lambda p: (np.abs(p[..., 0]) < 1.5) & (np.abs(p[..., 2] - 1.8) < 1.2),
        ),
    ]
    poses = np.stack(
        [camera_pose([0.1 * k, 0.0, 0.0], yaw=0.1 * k, pitch_down=np.radians(25)) for k in range(4)]
    )
    samples = [(render_depth(T, planes), T) for T in poses]
    up = estimate_up(poses, samples, INTR)
    assert angle_deg(up, [0, -1, 0]) < 1.5


def test_no_depth_or_no_plane_returns_guess():
    _, poses = y_down_room()
    guess = cameras_up(poses)
    np.testing.assert_allclose(estimate_up(poses), guess)
    empty = [(np.zeros((60, 80), np.float32), T) for T in poses]
    np.testing.assert_allclose(estimate_up(poses, empty, INTR), guess)


def test_z_up_world_and_frames_helper():
    """A z-up world (floor z = 0, cameras 1.4 m up): the estimate is +z."""
    from ltc_cli.types import Frame

    planes = [((0.0, 0.0, 1.0), 0.0, None), ((1.0, 0.0, 0.0), 4.0, None)]
    poses = [
        camera_pose([0.2 * k, 0.0, 1.4], yaw=0.3 * k, pitch_down=np.radians(20), down=(0, 0, -1))
        for k in range(5)
    ]
    frames = [
        Frame(key=str(k), index=k, depth_m=render_depth(T, planes), T_world_camera=T, intrinsics=INTR)
        for k, T in enumerate(poses)
    ]
    up = estimate_up_from_frames(frames)
    assert angle_deg(up, [0, 0, 1]) < 1.0


@pytest.mark.parametrize("up", [(0, -1, 0), (0, 0, 1), (0, 0, -1), (-0.08, -0.95, -0.30)])
def test_up_rotation(up):
    R = up_rotation(np.array(up, float))
    assert is_rotation(R)
    u = np.array(up, float) / np.linalg.norm(up)
    np.testing.assert_allclose(R @ u, [0, 0, 1], atol=1e-9)


def test_up_rotation_rejects_zero():
    with pytest.raises(ValueError):
        up_rotation(np.zeros(3))


def test_dining_room_up():
    """The real dining room (README: up about (-0.08, -0.95, -0.30), not z-up)."""
    if not (DINING / "pose.txt").is_file():
        pytest.skip(f"{DINING} is absent")
    from ltc_cli.recordings.images import load_depth

    rows = np.loadtxt(DINING / "pose.txt")
    poses = np.stack([pose_matrix(r[:3], r[3:]) for r in rows])
    intr = Intrinsics(640, 480, 518.0, 519.0, 325.5, 253.5)
    samples = [
        (load_depth(DINING / "depth" / f"{i + 1}.pgm", 1000.0), poses[i]) for i in range(len(poses))
    ]
    up = estimate_up(poses, samples, intr)
    readme = np.array([-0.08, -0.95, -0.30])
    err = angle_deg(up, readme)
    print(
        f"\ndining-room up estimate {np.round(up, 3).tolist()} vs README {readme.tolist()}: "
        f"{err:.2f} deg apart (camera-only guess {angle_deg(cameras_up(poses), readme):.1f} deg)"
    )
    assert err < 8.0


def desk_facing_wall(pitch_deg: float):
    """A z-up office like tum-fr1-rpy: floor z = 0, a desk top z = 0.75 (x 0.3..1.4, |y| < 1.2) and
    the wall behind it x = 1.5, seen by a hand-held camera at z = 1.2 looking at the desk (towards
    +x), pitched down by ``pitch_deg`` and rolled and turned a little."""
    planes = [
        ((0.0, 0.0, 1.0), 0.0, None),
        ((0.0, 0.0, 1.0), 0.75, lambda p: (p[..., 0] > 0.3) & (p[..., 0] < 1.4) & (np.abs(p[..., 1]) < 1.2)),
        ((1.0, 0.0, 0.0), 1.5, None),
    ]
    rng = np.random.default_rng(7)
    poses = [
        camera_pose([rng.uniform(-0.1, 0.1), rng.uniform(-0.2, 0.2), 1.2], yaw=rng.uniform(-0.3, 0.3),
                    pitch_down=np.radians(pitch_deg + rng.uniform(-5, 5)), down=(0, 0, -1),
                    roll=np.radians(rng.uniform(-15, 15)))
        for _ in range(6)
    ]
    return planes, np.stack(poses)


def test_camera_looking_down_at_a_desk_finds_the_desk_not_the_wall():
    """Pitched down by about 42 degrees (tum-fr1-rpy: 39-41), the cameras' guess leans towards the
    wall they face: the desk's normal is about 42 degrees from the guess, the wall's about 48. The
    desk must win (the cameras would look up by about 48 degrees under the wall's normal); a search
    limited to 30 degrees around the guess found neither and left the map tilted."""
    planes, poses = desk_facing_wall(42.0)
    guess = cameras_up(poses)
    assert 35 < angle_deg(guess, [0, 0, 1]) < 50
    samples = [(render_depth(T, planes), T) for T in poses]
    up = estimate_up(poses, samples, INTR)
    assert angle_deg(up, [0, 0, 1]) < 1.0


def test_mean_elevation_by_hand():
    from ltc_cli.ingest.frame_setup import mean_elevation_deg

    # Optical axes pitched down by 10 and 30 degrees in a z-up world: mean elevation -20 degrees;
    # under +x (the direction they face) as "up", they look up by 90 - 10 and 90 - 30: 70 degrees.
    poses = np.stack([camera_pose([0, 0, 1], yaw=0.0, pitch_down=np.radians(a), down=(0, 0, -1)) for a in (10, 30)])
    assert mean_elevation_deg(poses, np.array([0, 0, 1.0])) == pytest.approx(-20.0, abs=1e-9)
    facing = poses[0, :3, 2] * [1, 1, 0]
    assert mean_elevation_deg(poses, facing) == pytest.approx(70.0, abs=1e-9)


def test_tum_fr1_rpy_up_is_the_desk_normal():
    """tum-fr1-rpy (hand-held, pitched about 40 degrees down at a desk; its mocap world is z-up: the
    desk's normal lies within 2 degrees of z): the recording asks for an estimate, which must come
    out upright. Before issue 9's seventh round it was 22 degrees off (the desk lay outside the
    search cone around the cameras' guess)."""
    tum = SHARED / "data" / "tum-fr1-rpy"
    if not (tum / "groundtruth.txt").is_file():
        pytest.skip(f"{tum} is absent")
    from ltc_cli.ingest.frame_setup import frame_setup_for
    from ltc_cli.recordings.open import open_recording

    rec = open_recording(tum)
    assert rec.up == "estimate"
    R_up, floor_z, _ = frame_setup_for(rec)
    up = R_up[2]  # the recording's direction the map made +z
    assert angle_deg(up, [0, 0, 1]) < 5.0
    assert angle_deg(cameras_up(np.array([rec.frames[i].load().T_world_camera for i in (0, 100, 200)])),
                     [0, 0, 1]) > 25  # the cameras alone are far off


def test_sample_positions_by_hand():
    from ltc_cli.ingest.sampling import sample_positions

    # 6 of 232: i * 231 // 5 for i = 0, 1, 2 and their mirrors 231 - p.
    assert sample_positions(232, 6) == [0, 46, 92, 139, 185, 231]
    assert sample_positions(231, 5) == [0, 57, 115, 173, 230]  # 230 / 2 = 115 is the middle frame
    assert sample_positions(232, 5) == [0, 57, 174, 231]  # no middle frame: one fewer
    assert sample_positions(4, 6) == [0, 1, 2, 3]
    assert sample_positions(0, 6) == []
    for n_frames in range(1, 60):
        for n in range(2, 30):
            pos = sample_positions(n_frames, n)
            assert pos == sorted(n_frames - 1 - p for p in pos)  # the same set read backwards
            assert len(pos) in (min(n, n_frames), n - 1) and len(set(pos)) == len(pos)


def looking_down_with_tilt(tilt_deg: float) -> tuple:
    """(depth (H, W), T_world_camera) of a camera 1 m above the floor z = 0 looking straight down,
    whose recorded pose is rotated by ``tilt_deg`` about the world x axis (a pose error): the floor
    then lies on the plane whose normal is z tilted by that angle about x."""
    T_true = camera_pose([0.0, 0.0, 1.0], yaw=0.0, pitch_down=np.radians(90), down=(0, 0, -1))
    depth = render_depth(T_true, [((0.0, 0.0, 1.0), 0.0, None)])
    T_recorded = T_true.copy()
    c, s = np.cos(np.radians(tilt_deg)), np.sin(np.radians(tilt_deg))
    T_recorded[:3, :3] = np.array([[1, 0, 0], [0, c, -s], [0, s, c]]) @ T_true[:3, :3]
    return depth, T_recorded


def test_refine_up_averages_the_frames_own_planes():
    """Three frames whose poses tilt the floor by 2, 4 and 12 degrees about x, every pixel on the
    floor (equal support): within the 5 degree cone around z only the 2 and 4 degree frames count,
    and their mean normal lies at 3 degrees; the second pass, around 3 degrees, still leaves out the
    12 degree frame (9 degrees away). With a 15 degree cone all three count: the mean of the unit
    normals at 2, 4 and 12 degrees, atan2(sum sin, sum cos)."""
    from ltc_cli.ingest.frame_setup import refine_up

    samples = [looking_down_with_tilt(a) for a in (2.0, 4.0, 12.0)]
    for depth, _ in samples:
        assert (depth > 0).all()
    up = refine_up(np.array([0.0, 0.0, 1.0]), samples, INTR)
    assert angle_deg(up, [0, 0, 1]) == pytest.approx(3.0, abs=1e-3)
    assert abs(up[0]) < 1e-6  # tilted about x only
    a = np.radians([2.0, 4.0, 12.0])
    expected = np.degrees(np.arctan2(np.sin(a).sum(), np.cos(a).sum()))
    up = refine_up(np.array([0.0, 0.0, 1.0]), samples, INTR, cone_deg=15.0)
    assert angle_deg(up, [0, 0, 1]) == pytest.approx(expected, abs=1e-3)
    # No plane within the cone: the input comes back.
    np.testing.assert_array_equal(refine_up(np.array([1.0, 0.0, 0.0]), samples, INTR), [1.0, 0.0, 0.0])


def test_tum_fr1_rpy_read_backwards_gets_the_same_map_frame():
    """The up axis comes from frames spread the same from either end, so a pass in reverse order
    shares the forward pass's map frame (5 frames taken from the front put them 0.96 degrees
    apart)."""
    tum = SHARED / "data" / "tum-fr1-rpy"
    if not (tum / "groundtruth.txt").is_file():
        pytest.skip(f"{tum} is absent")
    from ltc_cli.ingest.frame_setup import frame_setup_for
    from ltc_cli.recordings.open import open_recording

    forward = open_recording(tum)
    backward = open_recording(tum)
    backward.frames = backward.frames[::-1]
    R_f, floor_f, noise_f = frame_setup_for(forward)
    R_b, floor_b, noise_b = frame_setup_for(backward)
    np.testing.assert_allclose(R_b, R_f, atol=1e-12)
    assert floor_b == pytest.approx(floor_f, abs=1e-12)
    assert noise_f is not None and noise_b == noise_f  # the sensor is measured on the same frames

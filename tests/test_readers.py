"""Readers of existing layouts (plugins/readers.py): TUM RGB-D, 7-Scenes / 3DMatch, ScanNet export.

Every test writes a tiny recording (8x6 images) in the layout and checks depth scale (to metres), the
pose convention (camera-to-world), association, intrinsics, identity and the errors."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from ltc_cli.errors import ConfigError, FrameError, RecordingError
from ltc_cli.geometry.camera import pose_matrix
from ltc_cli.geometry.boxes import rot_z
from ltc_plugins import readers
from ltc_plugins.readers import ReplicaReader, ScanNetReader, SevenScenesReader, TumReader
from ltc_cli.recordings.open import open_recording

W, H = 8, 6


def write_rgb(path: Path, value=(10, 20, 30), size=(W, H), fmt=None):
    path.parent.mkdir(parents=True, exist_ok=True)
    arr = np.zeros((size[1], size[0], 3), np.uint8)
    arr[:] = value
    Image.fromarray(arr).save(path, format=fmt)


def write_depth(path: Path, raw: np.ndarray | int, size=(W, H)):
    path.parent.mkdir(parents=True, exist_ok=True)
    arr = np.broadcast_to(np.asarray(raw, dtype=np.uint16), (size[1], size[0])).copy()
    Image.fromarray(arr).save(path)


def write_matrix(path: Path, M: np.ndarray):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(" ".join(f"{v:.9g}" for v in row) for row in M) + "\n")


def quat_z(angle: float) -> list[float]:
    """(qx, qy, qz, qw) of a rotation by ``angle`` about z."""
    return [0.0, 0.0, float(np.sin(angle / 2)), float(np.cos(angle / 2))]


# --------------------------------------------------------------------------------------------------
# TUM


def make_tum(root: Path, name="rgbd_dataset_freiburg2_tiny", gt_override: str | None = None) -> Path:
    d = root / name
    rgb = {"1.000000": 100, "1.033000": 200, "1.066000": 300, "5.000000": 400}
    depth = {"1.005000": 5000, "1.040000": 10000, "1.300000": 2500}
    lines = ["# color images", "# timestamp filename"]
    for t, v in rgb.items():
        write_rgb(d / "rgb" / f"{t}.png", (v % 256, 0, 0))
        lines.append(f"{t} rgb/{t}.png")
    (d / "rgb.txt").write_text("\n".join(lines) + "\n")
    lines = ["# depth maps"]
    for t, v in depth.items():
        write_depth(d / "depth" / f"{t}.png", v)
        lines.append(f"{t} depth/{t}.png")
    (d / "depth.txt").write_text("\n".join(lines) + "\n")
    gt = gt_override or "\n".join(
        [
            "# ground truth trajectory",
            "# timestamp tx ty tz qx qy qz qw",
            "0.990 0 0 0 " + " ".join(map(str, quat_z(0.0))),
            "1.010 2 0 0 " + " ".join(map(str, quat_z(np.pi / 2))),
            "1.030 2 1 0 " + " ".join(map(str, quat_z(np.pi / 2))),
            "1.040 2 2 0 " + " ".join(map(str, quat_z(np.pi / 2))),
        ]
    )
    (d / "groundtruth.txt").write_text(gt + "\n")
    return d


def test_tum_association_depth_scale_and_interpolated_pose(tmp_path):
    d = make_tum(tmp_path)
    reader = TumReader()
    assert reader.sniff(d) and not reader.sniff(tmp_path)
    rec = reader.open(d, {})
    assert rec.format == "tum" and rec.up == "estimate"
    # 1.066 has no depth within 0.02 s, 5.0 has neither depth nor pose.
    assert [f.key for f in rec.frames] == ["1.000000", "1.033000"]
    assert [f.index for f in rec.frames] == [0, 1]
    assert rec.meta["unassociated"] == 2
    # Folder name says freiburg2: that sensor's calibration; size from the images.
    assert (rec.intrinsics.fx, rec.intrinsics.cy) == (520.9, 249.7)
    assert (rec.intrinsics.width, rec.intrinsics.height) == (W, H)

    f0 = rec.frames[0].load()
    assert f0.depth_m.dtype == np.float32 and f0.depth_m.shape == (H, W)
    np.testing.assert_allclose(f0.depth_m, 1.0)  # 5000 / 5000
    assert f0.rgb.shape == (H, W, 3) and f0.rgb[0, 0, 0] == 100
    # Halfway between identity at t=0.99 and a quarter turn at t=1.01: 45 degrees, x = 1 (slerp).
    np.testing.assert_allclose(f0.T_world_camera[:3, :3], rot_z(np.pi / 4), atol=1e-9)
    np.testing.assert_allclose(f0.T_world_camera[:3, 3], [1.0, 0.0, 0.0], atol=1e-9)
    assert f0.extra["timestamp"] == pytest.approx(1.0)
    assert f0.extra["depth_timestamp"] == pytest.approx(1.005)

    f1 = rec.frames[1].load()
    np.testing.assert_allclose(f1.depth_m, 2.0)  # nearest depth 1.040: 10000 / 5000
    np.testing.assert_allclose(f1.T_world_camera[:3, 3], [2.0, 1.3, 0.0], atol=1e-9)
    # Camera-to-world: the camera origin maps to the pose's translation.
    np.testing.assert_allclose(f1.T_world_camera @ [0, 0, 0, 1], [2.0, 1.3, 0.0, 1.0], atol=1e-9)


def test_tum_options_and_identity(tmp_path):
    d = make_tum(tmp_path, name="some_sequence")
    rec = TumReader().open(d, {})
    assert rec.meta["camera"] == "ros" and rec.intrinsics.fx == 525.0  # no freiburgN in the name

    rec = TumReader().open(
        d, {"camera": "fr3", "depth_scale": 1000, "up": "-y", "max_time_diff": 0.05}
    )
    assert rec.intrinsics.fx == 535.4
    assert rec.up == (0.0, -1.0, 0.0)
    # A wider window lets 1.066 pair with depth 1.040 (but that depth is 1.033's, which is closer).
    assert len(rec.frames) == 2
    np.testing.assert_allclose(rec.frames[0].load().depth_m, 5.0)  # 5000 / 1000

    rec = TumReader().open(d, {"intrinsics": {"fx": 100, "fy": 101, "cx": 4, "cy": 3}, "up": None})
    assert (rec.intrinsics.fx, rec.intrinsics.fy, rec.intrinsics.cx, rec.intrinsics.cy) == (100, 101, 4, 3)
    assert rec.up is None

    # The identity follows the content, not the folder: a moved copy keeps it.
    moved = tmp_path / "elsewhere" / "renamed"
    shutil.copytree(d, moved)
    assert TumReader().open(moved, {}).identity == TumReader().open(d, {}).identity
    assert len(rec.identity) == 16 and int(rec.identity, 16) >= 0
    (moved / "groundtruth.txt").write_text(
        (moved / "groundtruth.txt").read_text().replace("1.040 2 2 0", "1.040 2 2 1")
    )
    assert TumReader().open(moved, {}).identity != TumReader().open(d, {}).identity


@pytest.mark.parametrize(
    "options, fragment",
    [
        ({"camera": "fr9"}, "camera"),
        ({"depth_scale": -1}, "depth_scale"),
        ({"up": "sideways"}, "up"),
        ({"up": [0, 0, 0]}, "up"),
        ({"intrinsics": {"fx": 1}}, "intrinsics"),
        ({"depth_sclae": 1000}, "unknown option"),
    ],
)
def test_tum_bad_options(tmp_path, options, fragment):
    d = make_tum(tmp_path)
    with pytest.raises(ConfigError, match=fragment):
        TumReader().open(d, options)


def test_tum_bad_quaternion_is_a_frame_error(tmp_path):
    gt = "\n".join(
        [
            "0.990 0 0 0 0 0 0 1",
            "1.010 2 0 0 0 0 0 1",
            "1.030 2 1 0 0 0 0 2",  # |q| = 2: corrupt
            "1.040 2 2 0 0 0 0 1",
        ]
    )
    d = make_tum(tmp_path, gt_override=gt)
    rec = TumReader().open(d, {})
    rec.frames[0].load()  # its bracket is fine
    with pytest.raises(FrameError, match="quaternion") as err:
        rec.frames[1].load()
    assert "groundtruth.txt" in str(err.value) and "line 3" in str(err.value)


def test_tum_non_finite_pose_and_missing_image(tmp_path):
    gt = "0.990 0 0 0 0 0 0 1\n1.010 nan 0 0 0 0 0 1\n1.030 0 0 0 0 0 0 1\n1.040 0 0 0 0 0 0 1\n"
    d = make_tum(tmp_path, gt_override=gt)
    rec = TumReader().open(d, {})
    with pytest.raises(FrameError, match="non-finite"):
        rec.frames[0].load()
    (d / "depth" / "1.040000.png").unlink()
    with pytest.raises(FrameError, match="missing") as err:
        rec.frames[1].load()
    assert err.value.path.endswith("1.040000.png")


def test_tum_poses_are_scipys_slerp_frame_by_frame(tmp_path):
    """The reader interpolates every frame's pose at once; each must be what scipy's Slerp and
    numpy's interp give over the trajectory, also where quaternions change sign (the same rotation:
    the shorter arc), are slightly off unit length, or a frame stands exactly on a row. A row that
    is not a pose spoils only the frames it brackets, each with the line named."""
    from scipy.spatial.transform import Rotation, Slerp

    rng = np.random.default_rng(5)
    d = tmp_path / "rgbd_dataset_freiburg1_slerp"
    write_depth(d / "depth" / "d.png", 5000)  # every frame names this one image: poses only here
    gt_t = 1.0 + 0.05 * np.arange(30)  # rows 0.05 s apart, under max_pose_gap
    q = Rotation.random(30, random_state=rng).as_quat()
    q[1::3] *= -1
    q[2] *= 1.005
    xyz = rng.normal(size=(30, 3))
    rows = [f"{t:.6f} " + " ".join(f"{v:.17g}" for v in (*p, *r)) for t, p, r in zip(gt_t, xyz, q)]
    rows[20] = f"{gt_t[20]:.6f} nan 0 0 0 0 0 1"
    (d / "groundtruth.txt").write_text("\n".join(rows) + "\n")
    frame_t = np.unique(np.round(np.concatenate([rng.uniform(1.0, gt_t[-1], 60), gt_t[[0, 5, 29]]]), 6))
    for name, folder in (("rgb.txt", "rgb"), ("depth.txt", "depth")):
        (d / name).write_text("".join(f"{t:.6f} depth/d.png\n" for t in frame_t))
    rec = TumReader().open(d, {})
    assert [float(f.key) for f in rec.frames] == pytest.approx(frame_t.tolist())
    rows_t = np.array([float(r.split()[0]) for r in rows])
    slerp = Slerp(rows_t, Rotation.from_quat(q))
    spoilt = (frame_t > rows_t[19]) & (frame_t < rows_t[21])
    assert 0 < spoilt.sum() < len(frame_t) - 10
    for f, t, bad in zip(rec.frames, frame_t, spoilt):
        if bad:
            with pytest.raises(FrameError, match="line 21: pose has non-finite values"):
                f.pose()
            continue
        T = f.pose()
        np.testing.assert_allclose(T[:3, :3], slerp(t).as_matrix(), atol=1e-9)
        np.testing.assert_allclose(T[:3, 3], [np.interp(t, rows_t, xyz[:, k]) for k in range(3)], atol=1e-9)
        np.testing.assert_array_equal(T[3], [0, 0, 0, 1])


def test_tum_trajectory_files_read_at_once_or_line_by_line(tmp_path):
    """numpy reads a trajectory of eight numbers a line at once; a file with commas, or one that is
    broken, is read line by line: the same poses, or one line naming the problem."""
    d = make_tum(tmp_path)
    rec = TumReader().open(d, {})
    want = [f.pose() for f in rec.frames]
    gt = (d / "groundtruth.txt").read_text()
    (d / "groundtruth.txt").write_text(gt.replace("1.010 2 0 0 ", "1.010,2,0,0,"))
    assert [f.pose().tolist() for f in TumReader().open(d, {}).frames] == [T.tolist() for T in want]
    for broken, message in (("1.010 2 0 0 0 0 1", "line 4: expected 8 columns"),
                            ("1.010 2 zero 0 0 0 0 1", "pose values must be numbers"),
                            ("t1.010 2 0 0 0 0 0 1", "line 4: timestamp 't1.010' is not a number")):
        lines = gt.splitlines()
        lines[3] = broken  # the row at 1.010, under two comment lines
        (d / "groundtruth.txt").write_text("\n".join(lines) + "\n")
        with pytest.raises(RecordingError, match=message) as err:
            TumReader().open(d, {})
        assert err.value.path.endswith("groundtruth.txt")


def test_tum_recording_errors(tmp_path):
    d = make_tum(tmp_path)
    (d / "groundtruth.txt").unlink()
    with pytest.raises(RecordingError, match="poses") as err:
        TumReader().open(d, {})
    assert err.value.path.endswith("groundtruth.txt")
    # A trajectory file of the user's own can stand in for the ground truth.
    (d / "traj.txt").write_text("0.9 0 0 0 0 0 0 1\n1.1 0 0 0 0 0 0 1\n")
    rec = TumReader().open(d, {"poses": "traj.txt", "max_pose_gap": 0.5})
    assert [f.key for f in rec.frames] == ["1.000000", "1.033000"]
    (d / "rgb.txt").write_text("1.0 rgb/x.png extra-column\n")
    with pytest.raises(RecordingError, match="line 1") as err:
        TumReader().open(d, {"poses": "traj.txt"})
    assert err.value.path.endswith("rgb.txt")


# --------------------------------------------------------------------------------------------------
# 7-Scenes / 3DMatch


def make_7scenes(root: Path, with_intrinsics=True) -> Path:
    scene = root / "7-scenes-kitchen"
    seq = scene / "seq-01"
    T0 = pose_matrix([1.0, 2.0, 3.0], quat_z(0.3))
    for k in range(3):
        stem = f"frame-{k:06d}"
        if k == 2:
            write_rgb(seq / f"{stem}.color.jpg", fmt="JPEG")
        else:
            write_rgb(seq / f"{stem}.color.png")
        raw = np.full((H, W), 1500, np.uint16)
        raw[0, 0] = 65535  # 7-Scenes' "no reading"
        write_depth(seq / f"{stem}.depth.png", raw)
        write_matrix(seq / f"{stem}.pose.txt", T0)
    bad = T0.copy()
    bad[:3, :3] *= 1.5  # scaled: not a rotation
    write_matrix(seq / "frame-000001.pose.txt", bad)
    if with_intrinsics:  # 3DMatch keeps it beside the seq-XX folders
        write_matrix(scene / "camera-intrinsics.txt", np.array([[500, 0, 4.5], [0, 501, 3.5], [0, 0, 1]]))
    return scene


def test_7scenes_frames_depth_and_pose(tmp_path):
    scene = make_7scenes(tmp_path)
    seq = scene / "seq-01"
    reader = SevenScenesReader()
    assert reader.sniff(seq) and not reader.sniff(tmp_path)
    rec = reader.open(seq, {})
    assert rec.format == "7scenes" and rec.up == "estimate"
    assert [f.key for f in rec.frames] == ["frame-000000", "frame-000001", "frame-000002"]
    intr = rec.intrinsics
    assert (intr.width, intr.height, intr.fx, intr.fy, intr.cx, intr.cy) == (W, H, 500, 501, 4.5, 3.5)

    f0 = rec.frames[0].load()
    assert f0.depth_m[0, 0] == 0.0  # 65535 -> no reading
    np.testing.assert_allclose(f0.depth_m[1:, :], 1.5)  # millimetres
    np.testing.assert_allclose(f0.T_world_camera, pose_matrix([1.0, 2.0, 3.0], quat_z(0.3)), atol=1e-8)
    with pytest.raises(FrameError, match="not a rotation") as err:
        rec.frames[1].load()
    assert err.value.path.endswith("frame-000001.pose.txt")
    assert rec.frames[2].load().rgb_path.endswith(".color.jpg")


def with_bom(*paths: Path) -> None:
    """Each text file saved again with a UTF-8 byte-order mark, as Windows editors save them."""
    for path in paths:
        path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())


def test_text_files_with_a_byte_order_mark_read_as_without(tmp_path):
    d = make_tum(tmp_path)
    want = TumReader().open(d, {})
    with_bom(*(d / name for name in ("rgb.txt", "depth.txt", "groundtruth.txt")))
    got = TumReader().open(d, {})
    assert [f.key for f in got.frames] == [f.key for f in want.frames]
    assert [f.pose().tolist() for f in got.frames] == [f.pose().tolist() for f in want.frames]

    scene = make_7scenes(tmp_path / "7")
    want = SevenScenesReader().open(scene / "seq-01", {})
    with_bom(scene / "camera-intrinsics.txt", scene / "seq-01" / "frame-000000.pose.txt")
    got = SevenScenesReader().open(scene / "seq-01", {})
    assert got.intrinsics == want.intrinsics
    np.testing.assert_array_equal(got.frames[0].load().T_world_camera, want.frames[0].load().T_world_camera)

    lap = tmp_path / "lap1"
    shutil.copytree(Path(__file__).resolve().parent.parent / "sample_data" / "lap1", lap)
    want = open_recording(lap)
    with_bom(lap / "poses.txt")
    got = open_recording(lap)
    assert [f.pose().tolist() for f in got.frames] == [f.pose().tolist() for f in want.frames]


def test_7scenes_scene_folder_and_defaults(tmp_path):
    scene = make_7scenes(tmp_path, with_intrinsics=False)
    # A scene folder is claimed, but opening it says which sequences to give instead of merging.
    assert SevenScenesReader().sniff(scene)
    with pytest.raises(RecordingError, match="seq-01"):
        SevenScenesReader().open(scene, {})
    rec = SevenScenesReader().open(scene / "seq-01", {})
    assert (rec.intrinsics.fx, rec.intrinsics.cx, rec.intrinsics.cy) == (585.0, 320.0, 240.0)
    (scene / "seq-01" / "frame-000000.pose.txt").write_text("1 0 0\n0 1 x\n")
    with pytest.raises(FrameError, match="numbers"):
        rec.frames[0].load()


# --------------------------------------------------------------------------------------------------
# ScanNet


def make_scannet(root: Path) -> Path:
    d = root / "scene0000_00"
    T = pose_matrix([0.5, -1.0, 1.3], quat_z(1.0))
    for k in range(3):
        # Colour at twice the depth's resolution, as ScanNet's 1296x968 vs 640x480.
        write_rgb(d / "color" / f"{k}.jpg", (200, 100, 50), size=(2 * W, 2 * H), fmt="JPEG")
        write_depth(d / "depth" / f"{k}.png", 2200)
        write_matrix(d / "pose" / f"{k}.txt", T)
    (d / "pose" / "2.txt").write_text("-inf -inf -inf -inf\n" * 4)  # lost tracking
    K = np.eye(4)
    K[0, 0], K[1, 1], K[0, 2], K[1, 2] = 577.6, 578.7, 3.9, 2.9
    write_matrix(d / "intrinsic" / "intrinsic_depth.txt", K)
    write_matrix(d / "intrinsic" / "intrinsic_color.txt", 2 * K)
    return d


def test_scannet(tmp_path):
    d = make_scannet(tmp_path)
    reader = ScanNetReader()
    assert reader.sniff(d) and not reader.sniff(tmp_path)
    rec = reader.open(d, {})
    assert rec.format == "scannet" and rec.up is None  # ScanNet worlds are z-up
    assert [f.key for f in rec.frames] == ["0", "1", "2"]
    assert (rec.intrinsics.width, rec.intrinsics.height, rec.intrinsics.fx) == (W, H, 577.6)
    f = rec.frames[1].load()
    assert f.rgb.shape == (H, W, 3)  # resized to the depth's size
    assert abs(int(f.rgb[2, 3, 0]) - 200) < 8  # still the same colour (JPEG is lossy)
    np.testing.assert_allclose(f.depth_m, 2.2, rtol=1e-6)
    np.testing.assert_allclose(f.T_world_camera[:3, 3], [0.5, -1.0, 1.3])
    with pytest.raises(FrameError, match="non-finite") as err:
        rec.frames[2].load()
    assert err.value.path.endswith("2.txt")

    moved = tmp_path / "copy"
    shutil.copytree(d, moved)
    assert ScanNetReader().open(moved, {}).identity == rec.identity
    assert ScanNetReader().open(d, {"up": "estimate"}).up == "estimate"

    (d / "intrinsic" / "intrinsic_depth.txt").unlink()
    with pytest.raises(RecordingError, match="intrinsic_depth"):
        ScanNetReader().open(d, {})
    rec = ScanNetReader().open(d, {"intrinsics": [1, 2, 3, 4]})
    assert rec.intrinsics.fy == 2.0


def make_replica(root: Path, scale: float = 6553.5) -> Path:
    """Replica/room0 as NICE-SLAM distributes it: frames 0, 1 and 12, cam_params.json one level up."""
    scene = root / "Replica" / "room0"
    for i in (0, 1, 12):
        write_rgb(scene / "results" / f"frame{i:06d}.jpg", fmt="JPEG")
        write_depth(scene / "results" / f"depth{i:06d}.png", 6553 + i)
    T = [pose_matrix([0.0, 0.0, float(i)], quat_z(0.1 * i)) for i in range(3)]
    (scene / "traj.txt").write_text("".join(" ".join(f"{v:.10f}" for v in M.ravel()) + "\n" for M in T))
    cam = {"w": W, "h": H, "fx": 600.0, "fy": 601.0, "cx": 3.5, "cy": 2.5, "scale": scale}
    (root / "Replica" / "cam_params.json").write_text(json.dumps({"camera": cam}))
    return scene


def test_replica_opens_with_no_option(tmp_path):
    scene = make_replica(tmp_path, scale=1000.0)
    assert ReplicaReader().sniff(scene)
    rec = open_recording(scene)  # chosen by sniffing; the camera and scale from ../cam_params.json
    assert rec.format == "replica" and [f.key for f in rec.frames] == ["frame000000", "frame000001", "frame000012"]
    i = rec.intrinsics
    assert (i.width, i.height, i.fx, i.fy, i.cx, i.cy) == (W, H, 600.0, 601.0, 3.5, 2.5)
    f = rec.frames[2].load()  # frame 12: depth 6553 + 12 at the file's scale, the third matrix
    assert f.depth_m[0, 0] == pytest.approx(6565 / 1000.0)
    np.testing.assert_allclose(f.T_world_camera, pose_matrix([0.0, 0.0, 2.0], quat_z(0.2)), atol=1e-9)
    assert open_recording(scene, None, {"depth_scale": 6553.5}).frames[2].load().depth_m[0, 0] == pytest.approx(
        6565 / 6553.5)  # the option wins
    cam = json.loads((tmp_path / "Replica" / "cam_params.json").read_text())
    (tmp_path / "Replica" / "cam_params.json").write_text(json.dumps({"camera": {**cam["camera"], "w": 1200}}))
    with pytest.raises(RecordingError, match="the camera is 1200x6, the depth images 8x6"):
        open_recording(scene)
    (tmp_path / "Replica" / "cam_params.json").unlink()
    with pytest.raises(RecordingError, match="no cam_params.json"):
        open_recording(scene)
    assert open_recording(scene, None, {"intrinsics": "5,6,3,2"}).intrinsics.fx == 5


def test_each_layout_is_claimed_by_its_reader_only(tmp_path):
    tum, scene, scannet = make_tum(tmp_path), make_7scenes(tmp_path), make_scannet(tmp_path)
    replica = make_replica(tmp_path)
    seq = scene / "seq-01"
    claims = {
        name: [r.name for r in readers.READERS if r.sniff(p)]
        for name, p in [("tum", tum), ("7scenes", seq), ("scannet", scannet), ("replica", replica)]
    }
    assert claims == {"tum": ["tum"], "7scenes": ["7scenes"], "scannet": ["scannet"], "replica": ["replica"]}
    assert not any(r.sniff(tmp_path / "missing") for r in readers.READERS)


def test_registered_names():
    got = {}
    readers.register_readers(register=lambda name, obj: got.setdefault(name, obj))
    assert sorted(got) == ["7scenes", "replica", "scannet", "tum"]
    assert all(callable(r.sniff) and callable(r.open) for r in got.values())


@pytest.mark.parametrize("layout", ["tum", "7scenes", "scannet", "replica", "ltc-recording", "folder", "opengl-poses"])
def test_each_frame_tells_the_pose_its_load_gives(tmp_path, layout):
    """FrameRef.pose, read before the images (a still camera's frames are judged by it and never
    loaded, ingest/keyframes.py): the very pose the frame's load gives, for every reader and with
    the poses read in another convention."""
    from ltc_cli.recordings.conventions import read_poses_as

    sample = Path(__file__).resolve().parent.parent / "sample_data" / "lap1"
    made = {"tum": lambda: make_tum(tmp_path), "7scenes": lambda: make_7scenes(tmp_path) / "seq-01",
            "scannet": lambda: make_scannet(tmp_path), "replica": lambda: make_replica(tmp_path)}
    if layout in made:
        rec = open_recording(made[layout]())
    elif layout == "folder":  # the sample's images and poses.txt, without recording.yaml
        shutil.copytree(sample, tmp_path / "plain", ignore=shutil.ignore_patterns("recording.yaml"))
        rec = open_recording(tmp_path / "plain", "folder", {"intrinsics": [525.0, 525.0, 319.5, 239.5]})
    else:
        rec = open_recording(sample)
        if layout == "opengl-poses":
            rec = read_poses_as(rec, "opengl")
    assert rec.frames and all(ref.pose is not None for ref in rec.frames)
    for ref in rec.frames[:6]:
        try:
            T = ref.load().T_world_camera
        except FrameError as exc:  # a bad pose (7-Scenes' frame 1 is scaled, ScanNet's 2 lost): the same error
            with pytest.raises(FrameError, match="not a rotation|non-finite") as err:
                ref.pose()
            assert (err.value.message, err.value.path) == (exc.message, exc.path)
            continue
        ref.pose()[:] = 0.0  # read once and kept: each call hands out a copy
        np.testing.assert_array_equal(ref.pose(), T)

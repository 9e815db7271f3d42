"""ROS bags (plugins/readers/rosbag.py): a small simulated lap written as a ROS 1 bag, a ROS 2
sqlite3 bag and a ROS 2 MCAP bag with rosbags' own writers (raw and compressed images, TF with a
static camera offset) maps to the same objects as the lap folder itself; TF chaining and
interpolation, and the image encodings, against values worked out by hand."""

from __future__ import annotations

import struct

import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from scipy.spatial.transform import Rotation

from ltc_cli.cli import cli
from ltc_cli.tools.simulate import simulate
from ltc_plugins.readers import ros_images
from ltc_plugins.readers.ros_tf import TfLookupError, TfTree
from ltc_plugins.readers.rosbag import RosbagReader
from tests.bags import T_BASE_LINK, T_LINK_OPTICAL, T_MAP_ODOM, detections_by_key, png_bytes, write_bag
from tests.test_folder_reader import assert_same_objects, objects_of


@pytest.fixture(scope="module")
def lap(tmp_path_factory):
    """A 12-frame lap of the tiny house at 160x120, and the objects ingesting it gives."""
    root = tmp_path_factory.mktemp("lap")
    simulate(root / "sim", scene="tiny", laps=1, seed=0, width=160, height=120, frames_per_room=12)
    lap = root / "sim" / "lap1"
    r = CliRunner().invoke(cli, ["ingest", str(lap), "--map", str(root / "lap.h5")])
    assert r.exit_code == 0, r.output
    return lap, objects_of(root / "lap.h5")


BAGS = {
    "ros1-raw-rgb8-16UC1": ("ros1", "x.bag", ("rgb8",), "16UC1", []),
    "ros2-sqlite3-jpeg-compressedDepth": ("sqlite3", "x", ("jpeg",), "compressedDepth", []),
    "ros2-mcap-bgr8-32FC1": ("mcap", "x", ("bgr8", "png"), "32FC1", ["-r", "color_topic=/camera/color/image_raw"]),
    "ros2-mcap-file-png": ("mcap", "x", ("png",), "16UC1", []),
}


@pytest.mark.parametrize("name", sorted(BAGS))
def test_bag_maps_like_the_lap_folder(name, lap, tmp_path):
    lap_dir, lap_objects = lap
    storage, bag_name, color, depth, extra = BAGS[name]
    bag = tmp_path / bag_name
    keys = write_bag(lap_dir, bag, storage, color=color, depth=depth)
    if name == "ros2-mcap-file-png":
        bag = next(bag.glob("*.mcap"))  # the storage file alone, without metadata.yaml
    assert RosbagReader().sniff(bag)
    dets = detections_by_key(lap_dir, keys, tmp_path / "dets")
    classes = yaml.safe_load((lap_dir / "recording.yaml").read_text())["classes"]
    r = CliRunner().invoke(cli, ["ingest", str(bag), "--map", str(tmp_path / "bag.h5"), *extra,
                                 "--set", f"detector.options.folder={dets}", "-r", f"classes={classes}"])
    assert r.exit_code == 0, r.output
    assert f"{len(keys)} frames ingested, 0 skipped" in r.output
    assert_same_objects(objects_of(tmp_path / "bag.h5"), lap_objects, tol=1e-3)


def test_frames_pair_colour_and_depth_by_stamp_and_chain_tf(lap, tmp_path):
    lap_dir, _ = lap
    keys = write_bag(lap_dir, tmp_path / "b.bag", "ros1", color=("rgb8",), depth="16UC1")
    rec = RosbagReader().open(tmp_path / "b.bag", {})
    assert rec.meta["world_frame"] == "map" and rec.meta["camera_frame"] == "camera_color_optical_frame"
    assert rec.meta["camera_info_topic"] == "/camera/aligned_depth_to_color/camera_info"  # the depth's sibling
    assert [f.key for f in rec.frames] == list(keys)  # colour stamps, 4 ms after their depth
    lap_poses = [ln.split() for ln in (lap_dir / "poses.txt").read_text().splitlines() if ln.strip()]
    f = rec.frames[5].load()
    np.testing.assert_array_equal(rec.frames[5].pose(), f.T_world_camera)  # known before the images are read
    want = np.array(lap_poses[5][1:], dtype=float)
    np.testing.assert_allclose(f.T_world_camera[:3, 3], want[:3], atol=1e-9)
    np.testing.assert_allclose(f.T_world_camera[:3, :3], Rotation.from_quat(want[3:]).as_matrix(), atol=1e-9)
    # Any two connected frames, either way up the tree: odom seen from the camera mount.
    rec = RosbagReader().open(tmp_path / "b.bag", {"world_frame": "camera_link", "camera_frame": "odom"})
    T_world_camera = np.eye(4)
    T_world_camera[:3, :3] = Rotation.from_quat(np.array(lap_poses[0][4:], dtype=float)).as_matrix()
    T_world_camera[:3, 3] = np.array(lap_poses[0][1:4], dtype=float)
    T_odom_base = np.linalg.inv(T_MAP_ODOM) @ T_world_camera @ np.linalg.inv(T_BASE_LINK @ T_LINK_OPTICAL)
    np.testing.assert_allclose(rec.frames[0].load().T_world_camera, np.linalg.inv(T_odom_base @ T_BASE_LINK),
                               atol=1e-9)


def test_a_frames_pose_is_looked_up_once(lap, tmp_path, monkeypatch):
    """An ingest asks a frame's pose before loading it (a still camera's frames), and the load
    needs it again: the TF chain is interpolated once, and each caller gets its own copy."""
    lap_dir, _ = lap
    write_bag(lap_dir, tmp_path / "b.bag", "ros1", color=("rgb8",), depth="16UC1")
    rec = RosbagReader().open(tmp_path / "b.bag", {})
    lookups, lookup = [], TfTree.lookup
    monkeypatch.setattr(TfTree, "lookup", lambda tree, *args, **kw: lookups.append(args) or lookup(tree, *args, **kw))
    T = rec.frames[3].pose()
    want = T.copy()
    T[0, 3] += 99.0
    frame = rec.frames[3].load()
    assert len(lookups) == 1
    np.testing.assert_array_equal(frame.T_world_camera, want)
    np.testing.assert_array_equal(rec.frames[3].pose(), want)
    rec.frames[4].load()
    assert len(lookups) == 2


def test_ambiguous_or_missing_topics_are_one_line(lap, tmp_path):
    lap_dir, _ = lap
    write_bag(lap_dir, tmp_path / "x.bag", "ros1", color=("rgb8", "jpeg"), depth="16UC1")
    r = CliRunner().invoke(cli, ["ingest", str(tmp_path / "x.bag"), "--map", str(tmp_path / "m.h5")])
    assert r.exit_code == 1
    assert r.output.strip().splitlines() == [
        f"Error: {tmp_path / 'x.bag'}: several colour topics: /camera/color/image_raw, "
        "/camera/color/image_raw/compressed; choose one with -r color_topic=TOPIC"]
    assert not (tmp_path / "m.h5").exists()
    r = CliRunner().invoke(cli, ["ingest", str(tmp_path / "x.bag"), "--map", str(tmp_path / "m.h5"),
                                 "-r", "color_topic=/nope"])
    assert r.exit_code == 1 and "no topic /nope in the bag" in r.output
    r = CliRunner().invoke(cli, ["ingest", str(tmp_path / "x.bag"), "--map", str(tmp_path / "m.h5"),
                                 "-r", "color_topic=/camera/color/image_raw", "-r", "camera_frame=lens"])
    assert r.exit_code == 1 and "tf has no frame 'lens'" in r.output and "base_link" in r.output


# -- TF, by hand ------------------------------------------------------------------------------------

def tree() -> TfTree:
    """map -> odom (static, 1 m along x); odom -> base (t = 0 s: identity; t = 1 s: 2 m along x and
    a quarter turn left); base -> cam (static, 1 m up)."""
    tf = TfTree()
    tf.add("map", "odom", 0, [1, 0, 0], [0, 0, 0, 1], static=True)
    tf.add("odom", "base", 0, [0, 0, 0], [0, 0, 0, 1], static=False)
    tf.add("odom", "base", 10**9, [2, 0, 0], [0, 0, np.sin(np.pi / 4), np.cos(np.pi / 4)], static=False)
    tf.add("/base", "cam", 0, [0, 0, 1], [0, 0, 0, 1], static=True)  # a leading slash (ROS 1) is dropped
    return tf


def test_tf_chains_and_interpolates():
    tf = tree()
    # Half way: base 1 m along odom's x, turned 45 degrees; map adds 1 m; the camera is 1 m above.
    T = tf.lookup("map", "cam", 5 * 10**8, max_gap_ns=10**9)
    np.testing.assert_allclose(T[:3, 3], [2, 0, 1], atol=1e-12)
    c = np.cos(np.pi / 4)
    np.testing.assert_allclose(T[:3, :3], [[c, -c, 0], [c, c, 0], [0, 0, 1]], atol=1e-12)
    # From the camera's side: the map origin seen from the camera at t = 1 s.
    T = tf.lookup("cam", "map", 10**9, max_gap_ns=10**9)
    np.testing.assert_allclose(T @ [3, 0, 1, 1], [0, 0, 0, 1], atol=1e-12)  # the camera sits at map (3, 0, 1)
    # Between siblings under odom: the camera in odom at t = 0.
    np.testing.assert_allclose(tf.lookup("odom", "cam", 0, 10**9)[:3, 3], [0, 0, 1])


def test_tf_refuses_what_it_cannot_know():
    tf = tree()
    with pytest.raises(TfLookupError, match="outside the times it covers"):
        tf.lookup("map", "cam", 2 * 10**9, max_gap_ns=10**9)
    with pytest.raises(TfLookupError, match="in a gap of 1 s"):
        tf.lookup("map", "cam", 5 * 10**8, max_gap_ns=10**8)
    np.testing.assert_allclose(tf.lookup("map", "cam", 10**9 + 5, 10**9, tolerance_ns=10)[:3, 3], [3, 0, 1])
    tf.add("world", "other", 0, [0, 0, 0], [0, 0, 0, 1], static=True)
    with pytest.raises(TfLookupError, match="not connected"):
        tf.lookup("map", "other", 0, 10**9)


# -- image encodings -------------------------------------------------------------------------------

class Msg:
    def __init__(self, **kw):
        self.__dict__.update(kw)


def test_raw_images_with_row_padding_and_byte_order():
    depth = np.array([[1000, 2500], [0, 65535]], dtype=">u2")
    padded = np.zeros((2, 6), np.uint8)  # step 6: 4 bytes of pixels and 2 of padding per row
    padded[:, :4] = depth.view(np.uint8).reshape(2, 4)
    msg = Msg(encoding="16UC1", height=2, width=2, step=6, is_bigendian=1, data=padded.ravel())
    np.testing.assert_allclose(ros_images.image_depth(msg, 1000.0), [[1.0, 2.5], [0.0, 65.535]], rtol=1e-6)
    metres = np.array([[1.5, np.nan], [-1.0, np.inf]], np.float32)
    msg = Msg(encoding="32FC1", height=2, width=2, step=8, is_bigendian=0, data=metres.view(np.uint8).ravel())
    np.testing.assert_array_equal(ros_images.image_depth(msg, 1000.0), [[1.5, 0], [0, 0]])
    bgr = np.array([[[1, 2, 3], [4, 5, 6]]], np.uint8)
    msg = Msg(encoding="bgr8", height=1, width=2, step=6, is_bigendian=0, data=bgr.ravel())
    np.testing.assert_array_equal(ros_images.image_rgb(msg), bgr[..., ::-1])
    with pytest.raises(ValueError, match="colour encoding 'yuv422'"):
        ros_images.image_rgb(Msg(encoding="yuv422", height=1, width=2, step=4, is_bigendian=0, data=bgr.ravel()))


def test_compressed_depth_16_and_32_bit():
    raw = np.array([[1000, 0], [2500, 4000]], np.uint16)
    msg = Msg(format="16UC1; compressedDepth png", data=struct.pack("<iff", 0, 0, 0) + png_bytes(raw))
    np.testing.assert_allclose(ros_images.compressed_depth(msg, 1000.0), [[1.0, 0], [2.5, 4.0]])
    # 32FC1: the PNG holds A / d + B (compressed_depth_image_transport's defaults A = 100 * 101,
    # B = 1 - A / 10); 2 m -> 5050 - 1009 = 4041, 5 m -> 2020 - 1009 = 1011, 0 = no reading.
    a, b = 10100.0, -1009.0
    inv = np.array([[4041, 1011], [0, 4041]], np.uint16)
    msg = Msg(format="32FC1; compressedDepth png", data=struct.pack("<iff", 0, a, b) + png_bytes(inv))
    np.testing.assert_allclose(ros_images.compressed_depth(msg, 1000.0), [[2.0, 5.0], [0.0, 2.0]], rtol=1e-6)
    # A plain 16-bit PNG (image_transport's "png" of 16UC1 depth): no header, the same values.
    msg = Msg(format="16UC1; png compressed", data=png_bytes(raw))
    assert ros_images.is_compressed_depth(msg.format) and not ros_images.is_compressed_depth("bgr8; jpeg compressed bgr8")
    np.testing.assert_allclose(ros_images.compressed_depth(msg, 1000.0), [[1.0, 0], [2.5, 4.0]])
    with pytest.raises(ValueError, match="RVL"):
        ros_images.compressed_depth(Msg(format="16UC1; compressedDepth rvl", data=b""), 1000.0)

"""Writing ROS bags from an ltc-recording/1 lap with rosbags' own writers (tests only).

The camera sits on a robot: ``/tf`` carries map -> odom (a fixed offset, republished) and
odom -> base_link (the motion), ``/tf_static`` base_link -> camera_link (a mount offset) ->
camera_color_optical_frame (the REP 103 optical rotation), so that map -> optical frame is the lap's
T_world_camera. Depth is stamped at the lap's frame times, colour 4 ms later (paired by stamp).
"""

from __future__ import annotations

import io
import struct
from pathlib import Path

import numpy as np
import yaml
from PIL import Image
from scipy.spatial.transform import Rotation

from ltc_cli.recordings.writer import quat_xyzw

T0_NS = 1_700_000_000 * 10**9
DT_NS = 100_000_000  # 10 Hz
COLOR_DELAY_NS = 4_000_000
OPTICAL = "camera_color_optical_frame"


def pose(t_xyz, R) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t_xyz
    return T


T_MAP_ODOM = pose([0.5, -0.2, 0.0], Rotation.from_euler("z", 0.1).as_matrix())
T_BASE_LINK = pose([0.2, 0.05, 0.8], Rotation.from_euler("y", 0.05).as_matrix())  # base_link -> camera_link
T_LINK_OPTICAL = pose([0.0, 0.015, 0.0], Rotation.from_euler("xyz", [-np.pi / 2, 0, -np.pi / 2]).as_matrix())


def lap_frames(lap: Path):
    """[(frame id, T_world_camera, rgb (H, W, 3) uint8, depth (H, W) uint16)] and recording.yaml."""
    meta = yaml.safe_load((lap / "recording.yaml").read_text())
    out = []
    for line in (lap / "poses.txt").read_text().split("\n"):
        if not line.strip():
            continue
        fid, *vals = line.split()
        v = np.array(vals, dtype=np.float64)
        T = pose(v[:3], Rotation.from_quat(v[3:]).as_matrix())
        out.append((fid, T, np.asarray(Image.open(lap / "rgb" / f"{fid}.png").convert("RGB")),
                    np.asarray(Image.open(lap / "depth" / f"{fid}.png")).astype(np.uint16)))
    return out, meta


def frame_key(stamp_ns: int) -> str:
    return f"{stamp_ns // 10**9}.{stamp_ns % 10**9:09d}"


class _Msgs:
    """Message constructors of one typestore (ROS 1 or ROS 2 field names)."""

    def __init__(self, ros1: bool):
        from rosbags.typesys import Stores, get_typestore

        self.ros1 = ros1
        self.store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
        if ros1:  # rosbags' noetic store lacks tf2_msgs; ROS 1's /tf has this type too
            from rosbags.typesys import get_types_from_msg

            self.store.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms",
                                                   "tf2_msgs/msg/TFMessage"))
        self.T = self.store.types

    def serialize(self, msg) -> bytes:
        f = self.store.serialize_ros1 if self.ros1 else self.store.serialize_cdr
        return bytes(f(msg, msg.__msgtype__))

    def header(self, stamp_ns, frame_id=OPTICAL):
        stamp = self.T["builtin_interfaces/msg/Time"](sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9)
        extra = {"seq": 0} if self.ros1 else {}
        return self.T["std_msgs/msg/Header"](**extra, stamp=stamp, frame_id=frame_id)

    def image(self, stamp_ns, arr: np.ndarray, encoding: str):
        h, w = arr.shape[:2]
        data = np.ascontiguousarray(arr).view(np.uint8).reshape(-1)
        return self.T["sensor_msgs/msg/Image"](header=self.header(stamp_ns), height=h, width=w, encoding=encoding,
                                               is_bigendian=0, step=data.size // h, data=data)

    def compressed(self, stamp_ns, data: bytes, fmt: str):
        return self.T["sensor_msgs/msg/CompressedImage"](header=self.header(stamp_ns), format=fmt,
                                                         data=np.frombuffer(data, np.uint8))

    def camera_info(self, stamp_ns, cam: dict):
        K = np.array([cam["fx"], 0, cam["cx"], 0, cam["fy"], cam["cy"], 0, 0, 1], dtype=np.float64)
        P = np.array([cam["fx"], 0, cam["cx"], 0, 0, cam["fy"], cam["cy"], 0, 0, 0, 1, 0], dtype=np.float64)
        roi = self.T["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0, width=0, do_rectify=False)
        mats = {"D": np.zeros(5), "K": K, "R": np.eye(3).ravel(), "P": P}
        if not self.ros1:
            mats = {k.lower(): v for k, v in mats.items()}  # ROS 2 spells them d, k, r, p
        return self.T["sensor_msgs/msg/CameraInfo"](header=self.header(stamp_ns), height=cam["height"],
                                                    width=cam["width"], distortion_model="plumb_bob", **mats,
                                                    binning_x=0, binning_y=0, roi=roi)

    def tf(self, stamp_ns, parent, child, T):
        q = quat_xyzw(T[:3, :3])
        tr = self.T["geometry_msgs/msg/Transform"](
            translation=self.T["geometry_msgs/msg/Vector3"](x=T[0, 3], y=T[1, 3], z=T[2, 3]),
            rotation=self.T["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3]))
        ts = self.T["geometry_msgs/msg/TransformStamped"](header=self.header(stamp_ns, parent), child_frame_id=child,
                                                          transform=tr)
        return ts

    def tf_message(self, transforms):
        return self.T["tf2_msgs/msg/TFMessage"](transforms=transforms)


def png_bytes(arr: np.ndarray) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(arr).save(buf, format="PNG")
    return buf.getvalue()


def jpeg_bytes(arr: np.ndarray) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(arr).save(buf, format="JPEG", quality=95)
    return buf.getvalue()


def compressed_depth_bytes(depth_u16: np.ndarray) -> bytes:
    """compressed_depth_image_transport's 16UC1 layout: a 12-byte header (format, A, B) then a PNG."""
    return struct.pack("<iff", 0, 0.0, 0.0) + png_bytes(depth_u16)


def write_bag(lap: Path, out: Path, storage: str, color: tuple[str, ...] = ("rgb8",), depth: str = "16UC1",
              depth_scale: float = 1000.0) -> dict:
    """A bag of the lap: ``storage`` "ros1", "sqlite3" or "mcap"; ``color`` any of "rgb8", "bgr8"
    (raw Image), "jpeg", "png" (CompressedImage on .../compressed); ``depth`` "16UC1", "32FC1" (raw)
    or "compressedDepth" (16UC1 PNG). Returns {frame key: lap frame id}."""
    frames, meta = lap_frames(lap)
    msgs = _Msgs(storage == "ros1")
    if storage == "ros1":
        from rosbags.rosbag1 import Writer

        writer = Writer(out)
    else:
        from rosbags.rosbag2 import StoragePlugin, Writer

        writer = Writer(out, version=9, storage_plugin=StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3)
    depth_topic = "/camera/aligned_depth_to_color/image_raw" + ("/compressedDepth" if depth == "compressedDepth" else "")
    keys = {}
    with writer:
        conns = {}

        def conn(topic, msgtype, **kw):
            if topic not in conns:
                if storage == "ros1" and topic == "/tf_static":
                    kw["latching"] = 1
                conns[topic] = writer.add_connection(topic, msgtype, typestore=msgs.store, **kw)
            return conns[topic]

        def write(topic, stamp_ns, msg):
            writer.write(conn(topic, msg.__msgtype__), stamp_ns, msgs.serialize(msg))

        static = [msgs.tf(T0_NS, "base_link", "camera_link", T_BASE_LINK),
                  msgs.tf(T0_NS, "camera_link", OPTICAL, T_LINK_OPTICAL)]
        write("/tf_static", T0_NS, msgs.tf_message(static))
        T_base_optical = T_BASE_LINK @ T_LINK_OPTICAL
        for i, (fid, T_world_camera, rgb, depth_u16) in enumerate(frames):
            t_depth = T0_NS + i * DT_NS
            t_color = t_depth + COLOR_DELAY_NS
            T_odom_base = np.linalg.inv(T_MAP_ODOM) @ T_world_camera @ np.linalg.inv(T_base_optical)
            write("/tf", t_depth, msgs.tf_message([msgs.tf(t_depth, "map", "odom", T_MAP_ODOM),
                                                   msgs.tf(t_depth, "odom", "base_link", T_odom_base)]))
            cam = meta["camera"]
            write("/camera/aligned_depth_to_color/camera_info", t_depth, msgs.camera_info(t_depth, cam))
            write("/camera/color/camera_info", t_color, msgs.camera_info(t_color, cam))
            if depth == "16UC1":
                write(depth_topic, t_depth, msgs.image(t_depth, depth_u16, "16UC1"))
            elif depth == "32FC1":
                metres = depth_u16.astype(np.float32) / np.float32(depth_scale)
                write(depth_topic, t_depth, msgs.image(t_depth, metres, "32FC1"))
            else:
                write(depth_topic, t_depth, msgs.compressed(t_depth, compressed_depth_bytes(depth_u16),
                                                            "16UC1; compressedDepth png"))
            for kind in color:
                if kind in ("rgb8", "bgr8"):
                    write("/camera/color/image_raw", t_color,
                          msgs.image(t_color, rgb if kind == "rgb8" else rgb[..., ::-1], kind))
                else:
                    data = jpeg_bytes(rgb) if kind == "jpeg" else png_bytes(rgb)
                    write("/camera/color/image_raw/compressed", t_color,
                          msgs.compressed(t_color, data, f"rgb8; {kind} compressed bgr8"))
            keys[frame_key(t_color)] = fid
    return keys


def detections_by_key(lap: Path, keys: dict, folder: Path) -> Path:
    """A detections folder whose files are named by the bag's frame keys (links to the lap's)."""
    folder.mkdir(parents=True, exist_ok=True)
    for key, fid in keys.items():
        (folder / f"{key}.json").symlink_to(lap / "detections" / f"{fid}.json")
    return folder

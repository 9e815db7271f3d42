"""ROS bag reader: ROS 1 ``.bag`` files and ROS 2 bags (a folder with metadata.yaml, or its
``.db3`` (sqlite3) or ``.mcap`` file), read with the ``rosbags`` package; no ROS installation.

What a frame is made of:

- colour: a ``sensor_msgs/Image`` (rgb8, bgr8, rgba8, bgra8, mono8) or ``CompressedImage`` (JPEG,
  PNG) topic;
- depth: an ``Image`` topic of 16UC1 (millimetres, ``depth_scale`` 1000) or 32FC1 (metres), or a
  ``compressedDepth`` CompressedImage topic, registered to the colour camera (same size and camera:
  ``aligned_depth_to_color``, ``depth_registered``);
- intrinsics: the first ``sensor_msgs/CameraInfo`` (``K`` in ROS 1, ``k`` in ROS 2) of the depth
  topic's namespace, else the colour topic's, else the only one (images are taken as rectified);
- pose: ``T_world_camera`` from ``/tf`` and ``/tf_static``, chained from ``world_frame`` (default
  ``map``, else ``odom``, else the root of the camera's tree) to ``camera_frame`` (default: the depth
  images' ``header.frame_id``, an optical frame: z forward, x right, y down) at the depth image's
  stamp, interpolated between TF stamps (:mod:`.ros_tf`).

Topics are chosen automatically when one topic fits each role; otherwise the reader stops with one
line listing the candidates, to be named with the options ``color_topic`` / ``depth_topic`` /
``camera_info_topic``. Colour and depth messages are paired by header stamp (nearest, within
``max_time_diff``, each depth image used once). A frame's key is its colour stamp ``sec.nanosec``.

Opening reads the bag once (headers, TF, camera info); each frame's ``load()`` then reads its two
images by their recorded time from the bag, which stays open while the recording is in use.
"""

from __future__ import annotations

import threading
import weakref
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ltc_cli import hookimpl
from ltc_cli.errors import FrameError, RecordingError
from ltc_cli.types import Frame, FrameRef, Recording
from ltc_plugins.readers import ros_images
from ltc_plugins.readers.common import (
    CLASSES_OPTION, associate_nearest, identity, intrinsics_option, make_intrinsics, open_folder, options_schema,
    up_option,
)  # fmt: skip
from ltc_plugins.readers.ros_tf import TfLookupError, TfTree

IMAGE, COMPRESSED = "sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage"
CAMERA_INFO, TF_MESSAGE = "sensor_msgs/msg/CameraInfo", "tf2_msgs/msg/TFMessage"
BAG_SUFFIXES = (".bag", ".db3", ".mcap")
WORLD_FRAMES = ("map", "odom")  # REP 105, in order of preference

_TOPIC = {"type": ["string", "null"], "minLength": 1, "default": None}
_SECONDS = {"type": "number", "exclusiveMinimum": 0}
OPTIONS_SCHEMA = options_schema(
    1000.0,
    None,  # REP 103: ROS worlds are z-up
    color_topic={**_TOPIC, "description": "colour Image or CompressedImage topic"},
    depth_topic={**_TOPIC, "description": "depth Image (16UC1, 32FC1) or compressedDepth topic"},
    camera_info_topic={**_TOPIC, "description": "CameraInfo topic of the (registered) depth images"},
    world_frame={**_TOPIC, "description": "tf frame of the map (default map, else odom, else the tf root)"},
    camera_frame={**_TOPIC, "description": "tf frame of the camera (default: the depth images' header.frame_id)"},
    max_time_diff={**_SECONDS, "default": 0.02, "description": "seconds between paired colour and depth stamps"},
    max_pose_gap={**_SECONDS, "default": 0.5, "description": "longest gap between tf stamps to interpolate over"},
    classes=CLASSES_OPTION,
)  # fmt: skip


def _stamp_ns(header) -> int:
    st = header.stamp
    return int(st.sec) * 1_000_000_000 + int(getattr(st, "nanosec", getattr(st, "nsec", 0)))


def _typestore():
    from rosbags.typesys import Stores, get_typestore

    # Only used for ROS 2 bags that carry no message definitions (older sqlite3 bags).
    return get_typestore(Stores.ROS2_HUMBLE)


@dataclass
class _Msg:
    bag_ns: int  # the time the bag recorded it (its index key)
    stamp_ns: int  # header.stamp
    frame_id: str


class _Bag:
    """An open bag shared by a recording's frames: raw messages by topic and record time."""

    def __init__(self, path: Path):
        from rosbags.highlevel import AnyReader

        self.path = path
        try:
            self.reader = AnyReader([path], default_typestore=_typestore())
            self.reader.open()
        except Exception as exc:  # rosbags raises its own errors, OSError, KeyError, ...
            raise RecordingError(f"cannot read the bag ({exc.__class__.__name__}: {exc})", path) from None
        self.lock = threading.Lock()
        self.by_topic: dict[str, list] = {}
        for c in self.reader.connections:
            self.by_topic.setdefault(c.topic, []).append(c)
        weakref.finalize(self, self.reader.close)

    def msgtype(self, topic: str) -> str:
        return self.by_topic[topic][0].msgtype

    def messages(self, topics, start=None, stop=None):
        conns = [c for t in topics for c in self.by_topic.get(t, [])]
        if not conns:
            return
        for conn, bag_ns, raw in self.reader.messages(connections=conns, start=start, stop=stop):
            yield conn.topic, bag_ns, raw, conn.msgtype

    def first(self, topic: str):
        for _, _, raw, msgtype in self.messages([topic]):
            return self.reader.deserialize(raw, msgtype)
        return None

    def read(self, topic: str, msg: _Msg):
        """The message of ``topic`` recorded at ``msg.bag_ns`` with header stamp ``msg.stamp_ns``."""
        with self.lock:
            found = [(raw, t) for _, _, raw, t in self.messages([topic], msg.bag_ns, msg.bag_ns + 1)]
        for raw, msgtype in found:
            obj = self.reader.deserialize(raw, msgtype)
            if _stamp_ns(obj.header) == msg.stamp_ns:
                return obj
        raise FrameError(f"topic {topic}: no message stamped {msg.stamp_ns / 1e9:.3f} s", self.path)


def _role(bag: _Bag, topic: str) -> str | None:
    """"color", "depth" or None for an image topic, from its first message."""
    msg = bag.first(topic)
    if msg is None:
        return None
    if bag.msgtype(topic) == COMPRESSED:
        return "depth" if ros_images.is_compressed_depth(str(msg.format)) else "color"
    enc = str(msg.encoding)
    if enc in ("16UC1", "32FC1") or (enc == "mono16" and "depth" in topic):
        return "depth"
    return "color" if enc in ros_images.COLOR_ENCODINGS else None


def _choose(kind: str, option: str, given: str | None, candidates: list[str], bag: _Bag) -> str:
    if given is not None:
        if given not in bag.by_topic:
            raise RecordingError(f"no topic {given} in the bag (its {kind} topics: {', '.join(candidates) or 'none'})",
                                 bag.path)
        return given
    if len(candidates) == 1:
        return candidates[0]
    if not candidates:
        raise RecordingError(f"no {kind} topic in the bag (topics: {', '.join(sorted(bag.by_topic))})", bag.path)
    raise RecordingError(f"several {kind} topics: {', '.join(candidates)}; choose one with -r {option}=TOPIC",
                         bag.path)


def _namespace(topic: str) -> str:
    parts = topic.rstrip("/").split("/")
    if parts[-1] in ("compressed", "compressedDepth"):
        parts = parts[:-1]
    return "/".join(parts[:-1])


def _info_topic(given, depth_topic, color_topic, bag: _Bag) -> str | None:
    infos = sorted(t for t in bag.by_topic if bag.msgtype(t) == CAMERA_INFO)
    if given is not None:
        return _choose("CameraInfo", "camera_info_topic", given, infos, bag)
    for image_topic in (depth_topic, color_topic):
        sibling = _namespace(image_topic) + "/camera_info"
        if sibling in infos:
            return sibling
    return _choose("CameraInfo", "camera_info_topic", None, infos, bag) if infos else None


class RosbagReader:
    """ROS 1 / ROS 2 bags (module docstring)."""

    name = "rosbag"
    OPTIONS_SCHEMA = OPTIONS_SCHEMA

    def sniff(self, path) -> bool:
        try:
            p = Path(path)
            if p.is_file():
                return p.suffix.lower() in BAG_SUFFIXES
            return (p / "metadata.yaml").is_file() and "rosbag2_bagfile_information" in (p / "metadata.yaml").read_text()
        except (OSError, UnicodeDecodeError):
            return False

    def open(self, path, options: dict | None = None) -> Recording:
        p = Path(path)
        if p.is_file():  # a ROS 1 bag, or a ROS 2 storage file (open_folder checks a folder)
            opts = open_folder(p.parent, options, OPTIONS_SCHEMA, self.name)[1]
        else:
            p, opts = open_folder(p, options, OPTIONS_SCHEMA, self.name)
        bag = _Bag(p)
        images = sorted(t for t in bag.by_topic if bag.msgtype(t) in (IMAGE, COMPRESSED))
        roles = {t: _role(bag, t) for t in images}
        color_topic = _choose("colour", "color_topic", opts["color_topic"], [t for t in images if roles[t] == "color"], bag)
        depth_topic = _choose("depth", "depth_topic", opts["depth_topic"], [t for t in images if roles[t] == "depth"], bag)
        info_topic = _info_topic(opts["camera_info_topic"], depth_topic, color_topic, bag)
        tf_topics = [t for t in bag.by_topic if bag.msgtype(t) == TF_MESSAGE]

        index: dict[str, list[_Msg]] = {color_topic: [], depth_topic: []}
        tree, info = TfTree(), None
        for topic, bag_ns, raw, msgtype in bag.messages([color_topic, depth_topic, *tf_topics, *([info_topic] if info_topic else [])]):
            msg = bag.reader.deserialize(raw, msgtype)
            if topic in index:
                index[topic].append(_Msg(bag_ns, _stamp_ns(msg.header), str(msg.header.frame_id).lstrip("/")))
            elif msgtype == TF_MESSAGE:
                static = topic.rstrip("/").endswith("tf_static")
                for tr in msg.transforms:
                    tt, rr = tr.transform.translation, tr.transform.rotation
                    tree.add(str(tr.header.frame_id), str(tr.child_frame_id), _stamp_ns(tr.header),
                             (tt.x, tt.y, tt.z), (rr.x, rr.y, rr.z, rr.w), static)
            elif info is None:
                info = msg
        colors, depths = index[color_topic], index[depth_topic]
        if not colors or not depths:
            raise RecordingError(f"topic {color_topic if not colors else depth_topic} has no messages", p)

        camera_frame = opts["camera_frame"] or depths[0].frame_id or colors[0].frame_id
        if not camera_frame:
            raise RecordingError("the depth images have no header.frame_id: give -r camera_frame=FRAME", p)
        frames = tree.frames
        if camera_frame not in frames:
            raise RecordingError(f"tf has no frame {camera_frame!r} (tf frames: {', '.join(sorted(frames)) or 'none'}); "
                                 "give -r camera_frame=FRAME", p)
        root = tree.root(camera_frame)  # frames of another tree can never give the camera's pose
        world_frame = opts["world_frame"] or next((f for f in WORLD_FRAMES if f in frames and tree.root(f) == root),
                                                  root)
        if world_frame not in frames:
            raise RecordingError(f"tf has no frame {world_frame!r} (tf frames: {', '.join(sorted(frames))})", p)
        if tree.root(world_frame) != root:
            raise RecordingError(f"tf does not connect {world_frame!r} and the camera frame {camera_frame!r} "
                                 f"(their trees' roots are {tree.root(world_frame)!r} and {root!r})", p)

        intr = self._intrinsics(opts, info, info_topic, bag, depth_topic, depths[0], p)
        chosen, d_idx = associate_nearest(np.array([m.stamp_ns / 1e9 for m in colors]),
                                          np.array([m.stamp_ns / 1e9 for m in depths]), float(opts["max_time_diff"]))
        loader = _Loader(bag, color_topic, depth_topic, intr, float(opts["depth_scale"]), tree, world_frame,
                         camera_frame, int(float(opts["max_pose_gap"]) * 1e9))
        refs, seen = [], set()
        for i in chosen:
            c = colors[i]
            key = f"{c.stamp_ns // 1_000_000_000}.{c.stamp_ns % 1_000_000_000:09d}"
            if key in seen:  # two colour images with one stamp: the first one is the frame
                continue
            seen.add(key)
            load = _FrameLoad(loader, key, len(refs), c, depths[int(d_idx[i])])
            refs.append(FrameRef(key, len(refs), load, pose=load.pose))
        if not refs:
            raise RecordingError(f"no {color_topic} image has a {depth_topic} image within "
                                 f"{opts['max_time_diff']} s", p)
        chosen_topics = f"{color_topic} {depth_topic} {info_topic} {world_frame} {camera_frame}"
        return Recording(
            path=str(p), format="rosbag",
            identity=identity([("topics", chosen_topics.encode()), ("frames", " ".join(sorted(seen)).encode()),
                               ("camera", repr((intr, float(opts["depth_scale"]))).encode())]),
            intrinsics=intr, frames=refs, up=up_option(opts, self.name), classes=opts.get("classes"),
            meta={"reader": self.name, "color_topic": color_topic, "depth_topic": depth_topic,
                  "camera_info_topic": info_topic, "world_frame": world_frame, "camera_frame": camera_frame,
                  "depth_scale": float(opts["depth_scale"]), "unassociated": len(colors) - len(refs)},
        )

    @staticmethod
    def _intrinsics(opts, info, info_topic, bag: _Bag, depth_topic: str, first_depth: _Msg, path):
        override = intrinsics_option(opts)
        if info is not None:
            K = np.asarray(info.k if hasattr(info, "k") else info.K, dtype=np.float64).reshape(3, 3)  # ROS 2 / ROS 1
            if K[0, 0] <= 0 or K[1, 1] <= 0:
                raise RecordingError(f"topic {info_topic}: CameraInfo has no calibration (K is {K.ravel().tolist()}); "
                                     "give -r intrinsics=FX,FY,CX,CY", path)
            return make_intrinsics(info.width, info.height, (K[0, 0], K[1, 1], K[0, 2], K[1, 2]), override)
        if override is None:
            raise RecordingError("the bag has no CameraInfo topic: give -r intrinsics=FX,FY,CX,CY", path)
        depth = _decode_depth(bag.read(depth_topic, first_depth), bag.msgtype(depth_topic), 1000.0)
        return make_intrinsics(depth.shape[1], depth.shape[0], override, None)


def _decode_depth(msg, msgtype: str, depth_scale: float) -> np.ndarray:
    if msgtype == COMPRESSED:
        return ros_images.compressed_depth(msg, depth_scale)
    return ros_images.image_depth(msg, depth_scale)


@dataclass
class _Loader:
    bag: _Bag
    color_topic: str
    depth_topic: str
    intrinsics: object
    depth_scale: float
    tree: TfTree
    world_frame: str
    camera_frame: str
    max_gap_ns: int

    def pose(self, depth: _Msg) -> np.ndarray:
        """T_world_camera (4, 4) at the depth image's stamp, from the bag's tf (FrameError if none)."""
        try:
            return self.tree.lookup(self.world_frame, self.camera_frame, depth.stamp_ns, self.max_gap_ns)
        except TfLookupError as exc:
            raise FrameError(f"{self.depth_topic} at {depth.stamp_ns / 1e9:.3f} s: {exc}", self.bag.path) from None

    def frame(self, key: str, index: int, color: _Msg, depth: _Msg, T: np.ndarray) -> Frame:
        bag, intr = self.bag, self.intrinsics
        where = f"{self.depth_topic} at {depth.stamp_ns / 1e9:.3f} s"
        try:
            depth_m = _decode_depth(bag.read(self.depth_topic, depth), bag.msgtype(self.depth_topic), self.depth_scale)
            where = f"{self.color_topic} at {color.stamp_ns / 1e9:.3f} s"
            cmsg = bag.read(self.color_topic, color)
            rgb = ros_images.compressed_rgb(cmsg) if bag.msgtype(self.color_topic) == COMPRESSED else ros_images.image_rgb(cmsg)
        except ValueError as exc:
            raise FrameError(f"{where}: {exc}", bag.path) from None
        for what, arr in (("depth", depth_m), ("colour", rgb)):
            if arr.shape[:2] != (intr.height, intr.width):
                raise FrameError(f"{what} image at {key} is {arr.shape[1]}x{arr.shape[0]}, the camera is "
                                 f"{intr.width}x{intr.height} (depth must be registered to the colour image)", bag.path)
        if not depth_m.any():
            raise FrameError(f"{self.depth_topic} at {key}: depth image has no readings (every pixel is 0)", bag.path)
        return Frame(key=key, index=index, depth_m=depth_m, T_world_camera=T, intrinsics=intr, rgb=rgb,
                     extra={"timestamp": color.stamp_ns / 1e9, "depth_timestamp": depth.stamp_ns / 1e9})


@dataclass
class _FrameLoad:
    """A frame's ``load()``: a plain object rather than a closure, so frames stay cheap to hold."""

    loader: _Loader
    key: str
    index: int
    color: _Msg
    depth: _Msg

    T: np.ndarray | None = None  # the pose once looked up: the ingest asks before loading, and the load again

    def __call__(self) -> Frame:
        return self.loader.frame(self.key, self.index, self.color, self.depth, self.pose())

    def pose(self) -> np.ndarray:
        if self.T is None:
            self.T = self.loader.pose(self.depth)
        return self.T.copy()


@hookimpl
def register_readers(register):
    register(RosbagReader.name, RosbagReader())

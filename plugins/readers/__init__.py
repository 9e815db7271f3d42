"""Recording readers (DESIGN.md section 3): the native ``ltc-recording/1`` layout
(:mod:`.ltc_recording`, its own entry point) and the layouts users already have: TUM RGB-D
(:mod:`.tum`), 7-Scenes / 3DMatch (:mod:`.seven_scenes`), the ScanNet export layout
(:mod:`.scannet`) and Replica as NICE-SLAM distributes it (:mod:`.replica`), all built on
:mod:`.common`. A plain folder of images with the camera given as
options (:mod:`.folder`) and ROS bags (:mod:`.rosbag`) are registered by entry points of their own.

Each reader has ``sniff(path) -> bool`` (cheap, never raises) and ``open(path, options) ->
Recording``. Opening parses the index and pose files only; images are read by each frame's lazy
``load()``, which also checks the pose and raises :class:`FrameError` naming the file at fault, so a
bad frame is skipped and counted instead of ending the ingest.

Options are checked against each reader's ``OPTIONS_SCHEMA`` (JSON Schema; an unknown option is an
error). Common to the readers of existing layouts (all optional):

- ``depth_scale``: metres = stored value / depth_scale (TUM 5000, 7-Scenes and ScanNet 1000).
- ``intrinsics``: ``{fx, fy, cx, cy}`` (or a list in that order, or the text ``"fx,fy,cx,cy"``)
  overriding the layout's camera (the plain folder's only source of it).
- ``up``: the world's up direction: ``"estimate"``, ``null`` (already z-up), an axis name such as
  ``"-y"`` or a 3-vector; overrides the layout's default (TUM and 7-Scenes: estimate; ScanNet: z-up).

TUM also takes ``camera`` (``fr1``, ``fr2``, ``fr3`` or ``ros``), ``poses`` (a trajectory file in the
TUM format to use instead of groundtruth.txt, relative to the recording), ``max_time_diff``
(seconds, default 0.02) and ``max_pose_gap`` (seconds, default 0.1). ``ltc-recording`` takes none:
everything is in its recording.yaml.

A recording's ``identity`` hashes the layout's index, intrinsics and pose files (names and bytes),
never the folder's path, so a recording moved elsewhere keeps its identity and frame keys.
"""

from __future__ import annotations

from ltc_cli import hookimpl
from ltc_plugins.readers.replica import ReplicaReader
from ltc_plugins.readers.scannet import ScanNetReader
from ltc_plugins.readers.seven_scenes import SevenScenesReader
from ltc_plugins.readers.tum import TumReader

READERS = (TumReader(), SevenScenesReader(), ScanNetReader(), ReplicaReader())


@hookimpl
def register_readers(register):
    for reader in READERS:
        register(reader.name, reader)


__all__ = ["READERS", "ReplicaReader", "ScanNetReader", "SevenScenesReader", "TumReader", "register_readers"]

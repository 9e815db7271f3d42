"""The worker's half of a distributed ingest, and what travels between worker and writer.

A Dask worker runs :class:`FrameTask` on one frame position of a recording: it opens the recording
and its detector (once per worker process, then cached), loads the frame, detects, maps the scores
to the map's classes and runs stage 1 (:func:`model_frame`). It sends back a :class:`RemoteFrame`:
the modeled boxes and their class vectors, the pose, the intrinsics, the frame's warnings, and of
the depth image only the pixels stage 4 reads (one per ``maintenance.ray_step`` block, the rays of
:func:`ray_grid`): 80 x 60 float32 (19 KB) instead of 640 x 480 (1.2 MB). The writer puts them back
into a full-size image that is zero elsewhere; stages 2-4 read exactly the same values, so the map
is the one a single process makes. The masks never travel.

Nothing here imports Dask: a worker needs ltc and its plugins installed, and the recordings at the
same paths as the writer (docs/fleet.md).
"""

from __future__ import annotations

import threading
import time
from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np

from ltc_cli.errors import FrameError, LtcError
from ltc_cli.pipeline.classes import ClassMapper
from ltc_cli.pipeline.frame_modeling import ClassFlags, FrameModel, in_map_classes, model_frame, most_confident
from ltc_cli.pipeline.visibility import ray_grid
from ltc_cli.recordings.open import open_recording, select_frames
from ltc_cli.recordings.saved_detections import detector_for
from ltc_cli.types import Frame, FrameWarning, Intrinsics

#: Recordings (with their detectors) a worker process keeps open; enough for the writers of a
#: manifest to interleave without reopening, bounded so a long-lived worker does not grow for ever.
CACHE_SIZE = 16


def depth_pixels(intr: Intrinsics, step: int) -> tuple[np.ndarray, np.ndarray]:
    """(rows, cols): the image rows and columns of the depth pixels stage 4 reads. ``pixel_counts``
    reads ``depth_m[v.astype(int), u.astype(int)]`` over :func:`ray_grid`, the product of these."""
    u, v = ray_grid(intr, step)
    return np.unique(v.astype(int)), np.unique(u.astype(int))


def pack_depth(depth_m: np.ndarray, intr: Intrinsics, step: int) -> np.ndarray:
    """(len(rows), len(cols)) depth samples, same dtype (see :func:`depth_pixels`)."""
    rows, cols = depth_pixels(intr, step)
    return np.ascontiguousarray(depth_m[np.ix_(rows, cols)])


def unpack_depth(samples: np.ndarray, shape: tuple, intr: Intrinsics, step: int) -> np.ndarray:
    """A (H, W) depth image holding ``samples`` where stage 4 reads and 0 (no reading) elsewhere."""
    rows, cols = depth_pixels(intr, step)
    depth_m = np.zeros(shape, dtype=samples.dtype)
    depth_m[np.ix_(rows, cols)] = samples
    return depth_m


@dataclass(frozen=True)
class RecordingJob:
    """What a worker needs for the frames of one recording (sent with every task: a few KB).

    settings: the effective settings (calibration applied); classes: the map's class list;
    T_up (4, 4): the up rotation of the recording's world; identity: the recording's, as the writer
    read it (a worker that reads another recording at the same path refuses).
    """

    path: str
    reader: str | None
    reader_options: dict | None
    identity: str
    settings: dict
    classes: tuple
    T_up: np.ndarray
    floor_z: float | None
    depth_range: tuple
    depth_noise: float | None = None  # measured on the recording (modeling.depth_noise: auto)
    frames: slice | None = None  # --frames: the range mapped; positions are into it, as the writer's

    def cache_key(self) -> tuple:
        det = self.settings["detector"]
        return (self.path, self.reader, repr(self.reader_options), self.identity, repr(det), self.classes,
                repr(self.frames))


@dataclass
class RemoteFrame:
    """Stage 1 of one frame and what stages 2-4 need of it (see the module docstring)."""

    key: str
    T_world_camera: np.ndarray
    intrinsics: Intrinsics
    depth_shape: tuple
    depth_samples: np.ndarray
    stage1: FrameModel
    times: tuple  # (t0, t1, t2): before loading, after loading, after detection (worker clock)
    warnings: list[FrameWarning] = field(default_factory=list)


@dataclass
class Failure:
    """An LtcError raised on a worker, sent back as a value (so Dask does not retry a bad frame)."""

    message: str
    path: str | None
    frame: bool  # a bad frame (FrameError: skippable) rather than an unusable recording


class _Opened:
    def __init__(self, job: RecordingJob):
        self.recording = select_frames(open_recording(job.path, job.reader, job.reader_options), job.frames)
        if self.recording.identity != job.identity:
            raise LtcError("a Dask worker reads another recording at this path than the writer did "
                           "(workers must see the same files)", job.path)
        self.detector = detector_for(self.recording, job.settings["detector"])
        self.lock = None if getattr(self.detector, "thread_safe", False) else threading.Lock()
        self.classes = ClassMapper(self.detector.classes, list(job.classes), job.settings["integration"]["unassigned_score"])
        self.flags = ClassFlags.from_settings(list(job.classes), job.settings)

    def detect(self, frame):
        if self.lock is None:
            return self.detector.detect(frame)
        with self.lock:
            return self.detector.detect(frame)


_cache: OrderedDict = OrderedDict()
_cache_lock = threading.Lock()


def _opened(job: RecordingJob) -> _Opened:
    key = job.cache_key()
    with _cache_lock:
        if key in _cache:
            _cache.move_to_end(key)
            return _cache[key]
        opened = _cache[key] = _Opened(job)
        while len(_cache) > CACHE_SIZE:
            _cache.popitem(last=False)
        return opened


@dataclass(frozen=True)
class FrameTask:
    """``FrameTask(job)([(position, key), ...])``: load, detect and model frames of one recording on
    a worker; one result (a RemoteFrame, or a Failure) per frame."""

    job: RecordingJob

    def __call__(self, items) -> list:
        return [self.one(position, key) for position, key in items]

    def one(self, position: int, key: str):
        try:
            return self.run(position, key)
        except FrameError as exc:
            return Failure(exc.message, exc.path, True)
        except LtcError as exc:
            return Failure(exc.message, exc.path, False)

    def run(self, position: int, key: str) -> RemoteFrame:
        job = self.job
        opened = _opened(job)
        ref = opened.recording.frames[position]
        if ref.key != key:
            raise LtcError(f"a Dask worker finds frame {ref.key} where the writer has {key}", job.path)
        t0 = time.perf_counter()
        frame = ref.load()
        t1 = time.perf_counter()
        dets = opened.detect(frame)
        cap = job.settings["modeling"]["max_detections"]
        if len(dets) > cap:  # as the writer does (the warning is the writer's, see session.py)
            dets = most_confident(dets, cap)
        masks, vectors = in_map_classes(dets, opened.classes)
        t2 = time.perf_counter()
        stage1 = model_frame(masks, vectors, frame.depth_m, job.T_up @ frame.T_world_camera, frame.intrinsics,
                             job.depth_range, job.settings, opened.flags, job.floor_z,
                             job.depth_noise)
        stage1.seconds = time.perf_counter() - t2
        step = int(job.settings["maintenance"]["ray_step"])
        return RemoteFrame(ref.key, frame.T_world_camera, frame.intrinsics, frame.depth_m.shape,
                           pack_depth(frame.depth_m, frame.intrinsics, step), stage1, (t0, t1, t2),
                           list(frame.warnings))


def unpack(result, job: RecordingJob, index: int):
    """On the writer: what ``load_and_detect`` returns, (frame, stage1, t0, t1, t2), from a task's
    result; a Failure raises its error here, where the frame's turn comes."""
    if isinstance(result, Failure):
        raise (FrameError if result.frame else LtcError)(result.message, result.path)
    step = int(job.settings["maintenance"]["ray_step"])
    depth_m = unpack_depth(result.depth_samples, result.depth_shape, result.intrinsics, step)
    frame = Frame(result.key, index, depth_m, result.T_world_camera, result.intrinsics,
                  warnings=list(result.warnings))
    return (frame, result.stage1, *result.times)

"""Ingest sessions: recordings -> detector -> Mapper -> map store, with checkpoints and resume.

No printing here: the caller passes ``progress`` and ``warn`` callbacks and a ``should_stop``
predicate (the CLI sets it from SIGINT / SIGTERM). Every way out of :func:`ingest` after the map is
opened commits a whole map first, so nothing already in the map is lost.

``jobs`` > 1 overlaps loading and detection with mapping: a pool of ``jobs`` threads loads and
detects the next frames (at most ``2 * jobs`` ahead) while the calling thread maps the current one.
Frames are mapped strictly in recording order from results taken in that order, so the map is
exactly the one a sequential run (``jobs`` = 1) makes; frames already in the map are skipped without
being loaded; a bad frame, ``strict``, ``should_stop`` and checkpoints behave as in a sequential run,
and work still pending when the run stops (or fails) is cancelled and discarded. Threads suffice:
image decoding, zlib, numpy and onnxruntime release the GIL. A detector's ``detect`` is called from
one thread at a time unless the detector declares ``thread_safe = True`` (then up to ``jobs`` at
once); loading frames always runs in parallel.
"""

from __future__ import annotations

import json
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Callable

import numpy as np
import yaml

from . import __version__, plugins
from .errors import ConfigError, FrameError, LtcError, RecordingError
from .geometry import backproject, rotation_between, transform
from .modeling import estimate_floor_z
from .mapping import ClassMapper, Mapper, SemanticMap
from .validation import validate
from .store import MapLock, load_map, save_map
from .types import Recording


@dataclass
class IngestSummary:
    frames_done: int = 0
    frames_skipped: int = 0
    frames_already: int = 0
    detections: int = 0
    created: int = 0
    merged: int = 0
    removed: int = 0
    non_detections: int = 0
    objects: int = 0
    seconds: float = 0.0
    interrupted: bool = False
    session: int = 0
    stage_seconds: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        return asdict(self)


def now_iso() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def open_recording(path, reader: str | None = None, options: dict | None = None) -> Recording:
    """Open a recording with the named reader, or the first installed reader that recognises it."""
    p = Path(path)
    if not p.exists():
        raise RecordingError("recording does not exist", p)
    if reader:
        return plugins.get("readers", reader).factory.open(p, options or {})
    for name, reg in sorted(plugins.registry("readers").items()):
        if reg.factory.sniff(p):
            return reg.factory.open(p, options or {})
    known = ", ".join(sorted(plugins.registry("readers")))
    raise RecordingError(f"no reader recognises this folder (installed readers: {known})", p)


def load_calibration(path) -> dict:
    p = Path(path)
    try:
        doc = yaml.safe_load(p.read_text())
    except OSError as exc:
        raise ConfigError(f"cannot read calibration ({exc.strerror})", p) from None
    except yaml.YAMLError:
        raise ConfigError("calibration is not valid YAML", p) from None
    validate(doc, "calibration", p)
    return doc


def _sample_frames(rec: Recording, n: int) -> list:
    """Up to n readable frames spread over the recording."""
    step = max(1, len(rec.frames) // n)
    out = []
    for ref in rec.frames[::step][:n]:
        try:
            out.append(ref.load())
        except FrameError:
            continue
    return out


def frame_setup_for(rec: Recording, sample_frames: int = 5):
    """(R_up (3, 3), floor_z or None) of a recording.

    R_up turns the recording's world into the z-up map frame (given, or estimated from the
    cameras and the floor when ``up: estimate``); floor_z is the floor's height in the map frame,
    from the depth of a few frames (None when no floor is in view).
    """
    frames = _sample_frames(rec, sample_frames)
    if rec.up is None:
        R_up = np.eye(3)
    elif isinstance(rec.up, str) and rec.up == "estimate":
        from . import upaxis

        if not frames:
            raise RecordingError("cannot estimate the up axis: no readable frame", rec.path)
        up = upaxis.estimate_up(np.array([f.T_world_camera for f in frames]),
                                [(f.depth_m, f.T_world_camera) for f in frames], rec.intrinsics)
        R_up = rotation_between(up, [0.0, 0.0, 1.0])
    else:
        R_up = rotation_between(np.asarray(rec.up, dtype=np.float64), [0.0, 0.0, 1.0])
    zs = []
    for f in frames:
        v, u = np.mgrid[4 : f.depth_m.shape[0] : 8, 4 : f.depth_m.shape[1] : 8]
        z = f.depth_m[v, u]
        ok = z > 0
        pts = backproject(u[ok], v[ok], z[ok], f.intrinsics)
        zs.append(transform(f.T_world_camera, pts) @ R_up[2])
    floor_z = estimate_floor_z(np.concatenate(zs)) if zs else None
    return R_up, floor_z


def ingest(
    recording_paths: list,
    map_path,
    config: dict,
    *,
    reader: str | None = None,
    reader_options: dict | None = None,
    calibration: dict | None = None,
    checkpoint_every: int = 50,
    strict: bool = False,
    progress: Callable | None = None,
    warn: Callable[[str], None] | None = None,
    should_stop: Callable[[], bool] | None = None,
    on_frame: Callable | None = None,
    jobs: int = 1,
) -> IngestSummary:
    """Ingest recordings into the map at ``map_path`` (created when it does not exist).

    Frames already in the map (by recording identity and frame id) are skipped, so re-running an
    interrupted ingest resumes it, and re-running a finished one changes nothing. ``jobs`` > 1
    loads and detects frames ahead in that many threads; the map is the same (module docstring).
    """
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise ConfigError(f"jobs must be an integer >= 1, not {jobs!r}")
    warn = warn or (lambda msg: None)
    should_stop = should_stop or (lambda: False)
    t_start = time.perf_counter()
    map_path = Path(map_path)
    if calibration is not None:
        config["maintenance"]["v_other"] = float(calibration["v_other"])
        config["maintenance"]["v_other_per_class"] = {
            name: float(stats["v_other"]) for name, stats in (calibration.get("per_class") or {}).items()
            if isinstance(stats, dict) and stats.get("v_other") is not None
        }

    # Everything that can be checked before the map is touched is checked first.
    recordings = [open_recording(p, reader, reader_options) for p in recording_paths]
    metric_name = config["association"]["metric"]
    policy_name = config["maintenance"]["policy"]
    metric = plugins.get("metrics", metric_name).factory(config["association"])
    policy = plugins.get("policies", policy_name).factory(config["maintenance"])
    det_name = config["detector"]["name"]
    det_factory = plugins.get("detectors", det_name).factory
    detectors = [det_factory(rec, dict(config["detector"]["options"])) for rec in recordings]
    setups = [frame_setup_for(rec) for rec in recordings]
    ups = [R for R, _ in setups]
    floors = [z for _, z in setups]

    lock = MapLock(map_path).acquire()
    try:
        if map_path.exists():
            smap = load_map(map_path)
        else:
            classes = config["map"]["classes"] or recordings[0].classes or detectors[0].classes
            if not classes:
                raise ConfigError("no class list: give map.classes, or a recording with classes")
            smap = SemanticMap.new(classes)
            smap.created = now_iso()
            smap.up_rotation = ups[0]
        summary = _run(smap, map_path, config, recordings, detectors, ups, floors, metric, policy, calibration,
                       checkpoint_every, strict, progress, warn, should_stop, on_frame, jobs)
    finally:
        lock.release()
    summary.seconds = time.perf_counter() - t_start
    return summary


def _session_row(smap, config, recordings, ups, floors, calibration) -> tuple[int, dict]:
    sources = [str(Path(r.path).resolve()) for r in recordings]
    identities = [r.identity for r in recordings]
    last = smap.sessions[-1] if smap.sessions else None
    # An interrupted session over the same recordings is resumed, not started anew, so a resumed
    # ingest ends in exactly the map an uninterrupted one makes.
    if last is not None and last["status"] != "complete" and json.loads(last["recordings"]) == identities:
        last["status"] = "running"
        return len(smap.sessions) - 1, last
    settings = {k: v for k, v in config.items() if k != "detector"}
    row = {
        "started": now_iso(), "finished": "", "status": "running",
        "sources": json.dumps(sources), "recordings": json.dumps(identities),
        "readers": json.dumps([r.format for r in recordings]),
        "detector": json.dumps(config["detector"]), "metric": config["association"]["metric"],
        "policy": config["maintenance"]["policy"], "settings": json.dumps(settings),
        "v_other": float(config["maintenance"]["v_other"]), "ltc_version": __version__,
        "frames_done": 0, "frames_skipped": 0,
        "up_rotation": json.dumps([np.asarray(u).round(9).tolist() for u in ups]),
        "floor_z": json.dumps([None if z is None else round(float(z), 6) for z in floors]),
    }
    if calibration is not None:
        row["settings"] = json.dumps({**settings, "calibration": calibration})
    smap.sessions.append(row)
    return len(smap.sessions) - 1, row


def _load_and_detect(det, lock=None):
    """fetch(ref) -> (frame, detections, t0, t1, t2): load the frame (t0 -> t1), then detect (t1 ->
    t2); FrameError propagates. With a lock, ``detect`` runs under it and the wait is not timed."""

    def fetch(ref):
        t0 = time.perf_counter()
        frame = ref.load()
        t1 = time.perf_counter()
        if lock is None:
            dets = det.detect(frame)
            return frame, dets, t0, t1, time.perf_counter()
        with lock:
            td = time.perf_counter()
            dets = det.detect(frame)
            t2 = time.perf_counter()
        return frame, dets, t0, t1, t1 + (t2 - td)

    return fetch


class _Prefetch:
    """Loads and detects the frames of one recording ahead of the mapper in a thread pool.

    ``take(ref)`` returns what ``_load_and_detect`` returns for ``ref`` (or raises what it raised),
    for refs asked in recording order; frames whose key is in ``done`` when they come into the
    look-ahead window are never loaded. Everything is submitted from the calling thread, so ``done``
    (the map's frame keys) is only read there.
    """

    def __init__(self, refs, keys, done, det, jobs: int, lookahead: int | None = None):
        self.refs = list(refs)
        self.keys = list(keys)
        self.done = done
        self.position = {id(r): i for i, r in enumerate(self.refs)}
        lock = None if getattr(det, "thread_safe", False) else threading.Lock()
        self.fetch = _load_and_detect(det, lock)
        self.lookahead = max(1, lookahead or 2 * jobs)
        self.pool = ThreadPoolExecutor(max_workers=jobs, thread_name_prefix="ltc-detect")
        self.pending: dict = {}  # position -> Future
        self.next = 0  # the next position to consider for submission

    def take(self, ref):
        i = self.position[id(ref)]
        for j in [j for j in self.pending if j < i]:  # frames the caller skipped after all
            self.pending.pop(j).cancel()
        while self.next < len(self.refs) and (self.next <= i or len(self.pending) < self.lookahead):
            j = self.next
            self.next += 1
            if self.keys[j] not in self.done:
                self.pending[j] = self.pool.submit(self.fetch, self.refs[j])
        fut = self.pending.pop(i, None)
        if fut is None:  # not submitted (its key was already in the map then): do it here
            return self.fetch(ref)
        return fut.result()

    def close(self) -> None:
        """Cancel the work not started, wait for the frames in flight, drop every result."""
        for fut in self.pending.values():
            fut.cancel()
        self.pending.clear()
        self.pool.shutdown(wait=True, cancel_futures=True)


def _run(smap, map_path, config, recordings, detectors, ups, floors, metric, policy, calibration,
         checkpoint_every, strict, progress, warn, should_stop, on_frame, jobs=1) -> IngestSummary:
    session, row = _session_row(smap, config, recordings, ups, floors, calibration)
    mapper = Mapper(smap, config, metric, policy, session=session)
    summary = IngestSummary(session=session)
    stage = {k: 0.0 for k in ("load", "detect", "modeling", "association", "integration", "maintenance", "merge")}
    since_commit = 0
    error: BaseException | None = None
    ahead: _Prefetch | None = None
    try:
        for rec, det, R_up, floor_z in zip(recordings, detectors, ups, floors):
            mapper_classes = ClassMapper(det.classes, smap.classes)
            T_up = np.eye(4)
            T_up[:3, :3] = R_up
            m_cfg = config["modeling"]
            depth_range = rec.depth_range or (m_cfg["min_depth"], m_cfg["max_depth"])
            depth_range = (max(depth_range[0], m_cfg["min_depth"]), min(depth_range[1], m_cfg["max_depth"]))
            if jobs > 1:
                ahead = _Prefetch(rec.frames, [f"{rec.identity}/{r.key}" for r in rec.frames],
                                  smap.frame_keys, det, jobs)
            fetch = ahead.take if ahead is not None else _load_and_detect(det)
            for ref in rec.frames:
                if should_stop():
                    summary.interrupted = True
                    break
                key = f"{rec.identity}/{ref.key}"
                if key in smap.frame_keys:
                    summary.frames_already += 1
                    if progress:
                        progress(1)
                    continue
                try:
                    frame, dets, t0, t1, t2 = fetch(ref)
                except FrameError as exc:
                    if strict:
                        raise
                    warn(f"skipped frame {ref.key}: {exc}")
                    summary.frames_skipped += 1
                    row["frames_skipped"] += 1
                    if progress:
                        progress(1)
                    continue
                stage["load"] += t1 - t0
                stage["detect"] += t2 - t1
                masks, vectors = [], []
                for d in dets:
                    v = mapper_classes(d.scores)
                    if v is not None:
                        masks.append(d.mask)
                        vectors.append(v)
                res = mapper.process_frame(
                    ref.index, key, masks, vectors,
                    frame.depth_m, T_up @ frame.T_world_camera, frame.intrinsics, depth_range,
                    floor_z=floor_z,
                )
                for k, v in res.timings.items():
                    stage[k] += v
                smap.frame_keys.add(key)
                summary.frames_done += 1
                row["frames_done"] += 1
                summary.detections += res.detections
                summary.created += res.created
                summary.merged += res.merged
                summary.removed += res.removed
                summary.non_detections += res.non_detections
                since_commit += 1
                if on_frame:
                    on_frame(summary)
                if progress:
                    progress(1)
                if checkpoint_every and since_commit >= checkpoint_every:
                    save_map(smap, map_path)
                    since_commit = 0
            if ahead is not None:
                ahead.close()
                ahead = None
            if summary.interrupted:
                break
        k = config["maintenance"]["min_detections"]
        if not summary.interrupted and summary.frames_done > 0 and k > 1:
            summary.removed += mapper.prune_unconfirmed(k, -1, "end of session")
    except BaseException as exc:  # commit what is done, then let the error go on
        error = exc
        if ahead is not None:  # stop the look-ahead before committing; its results are dropped
            ahead.close()
    row["status"] = "interrupted" if (summary.interrupted or error is not None) else "complete"
    row["finished"] = now_iso()
    # A run that mapped no frame leaves the file as it was (and creates none): bad input never
    # changes a map.
    if summary.frames_done > 0:
        save_map(smap, map_path)
    summary.objects = len(smap.active_rows())
    summary.stage_seconds = stage
    if error is not None:
        raise error
    return summary


__all__ = ["ingest", "open_recording", "IngestSummary", "LtcError", "load_calibration"]

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
import time
from dataclasses import asdict, dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Callable

import numpy as np
import yaml

from ltc_cli import __version__, plugins
from ltc_cli.errors import ConfigError, FrameError, LtcError
from ltc_cli.ingest.frame_setup import frame_setup_for
from ltc_cli.ingest.prefetch import Prefetch, load_and_detect
from ltc_cli.pipeline.classes import ClassMapper
from ltc_cli.pipeline.mapper import Mapper
from ltc_cli.map.model import SemanticMap
from ltc_cli.validation import validate
from ltc_cli.map.store import MapLock, load_map, save_map
from ltc_cli.recordings.open import open_recording


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


def detections_source(det, frame) -> str:
    """The file a frame's detections came from, for warnings: a recorded detector's JSON file,
    else the image the detector saw."""
    folder = getattr(det, "folder", None)
    if folder is not None:
        return str(Path(folder) / f"{frame.key}.json")
    return str(frame.rgb_path or frame.key)


def most_confident(dets: list, k: int) -> list:
    """The k detections with the highest top score, in their original order."""
    top = np.argsort([-float(np.max(d.scores)) for d in dets], kind="stable")[:k]
    return [dets[i] for i in sorted(top)]


def _run(smap, map_path, config, recordings, detectors, ups, floors, metric, policy, calibration,
         checkpoint_every, strict, progress, warn, should_stop, on_frame, jobs=1) -> IngestSummary:
    n_sessions = len(smap.sessions)
    session, row = _session_row(smap, config, recordings, ups, floors, calibration)
    resumed = len(smap.sessions) == n_sessions
    mapper = Mapper(smap, config, metric, policy, session=session)
    summary = IngestSummary(session=session)
    stage = {k: 0.0 for k in ("load", "detect", "modeling", "association", "integration", "maintenance", "merge")}
    since_commit = 0
    completes = False
    max_dets = config["modeling"]["max_detections"]
    error: BaseException | None = None
    ahead: Prefetch | None = None
    try:
        for rec, det, R_up, floor_z in zip(recordings, detectors, ups, floors):
            mapper_classes = ClassMapper(det.classes, smap.classes)
            T_up = np.eye(4)
            T_up[:3, :3] = R_up
            m_cfg = config["modeling"]
            depth_range = rec.depth_range or (m_cfg["min_depth"], m_cfg["max_depth"])
            depth_range = (max(depth_range[0], m_cfg["min_depth"]), min(depth_range[1], m_cfg["max_depth"]))
            if jobs > 1:
                ahead = Prefetch(rec.frames, [f"{rec.identity}/{r.key}" for r in rec.frames],
                                  smap.frame_keys, det, jobs)
            fetch = ahead.take if ahead is not None else load_and_detect(det)
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
                if len(dets) > max_dets:
                    warn(f"{detections_source(det, frame)}: {len(dets)} detections in one frame, more than "
                         f"modeling.max_detections ({max_dets}); kept the {max_dets} most confident")
                    dets = most_confident(dets, max_dets)
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
        # A resumed session whose frames were all committed before the kill still ends here: it is
        # finished (pruned, marked complete) exactly as an uninterrupted run would have finished it.
        completes = summary.frames_done > 0 or (resumed and not summary.interrupted)
        k = config["maintenance"]["min_detections"]
        if not summary.interrupted and completes and k > 1:
            summary.removed += mapper.prune_unconfirmed(k, -1, "end of session")
    except BaseException as exc:  # commit what is done, then let the error go on
        error = exc
        if ahead is not None:  # stop the look-ahead before committing; its results are dropped
            ahead.close()
    row["status"] = "interrupted" if (summary.interrupted or error is not None) else "complete"
    row["finished"] = now_iso()
    # A run that mapped no frame leaves the file as it was (and creates none): bad input never
    # changes a map.
    if summary.frames_done > 0 or (completes and error is None):
        save_map(smap, map_path)
    summary.objects = len(smap.active_rows())
    summary.stage_seconds = stage
    if error is not None:
        raise error
    return summary


__all__ = ["ingest", "open_recording", "IngestSummary", "LtcError", "load_calibration"]

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

``revisit`` ingests recordings that are already in the map again, as a new session: the same route
driven again. Each session has a visit number (1 for a recording's first ingest); frames of visit v > 1
are keyed ``IDENTITY@v/FRAME`` instead of ``IDENTITY/FRAME``, so they do not collide with an earlier
visit's while an interrupted revisit still finds its own frames and resumes.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from ltc_cli import plugins
from ltc_cli.config import settings_from
from ltc_cli.errors import ConfigError, FrameError, LtcError
from ltc_cli.ingest.frame_setup import frame_setup_for
from ltc_cli.ingest.frame_warnings import detections_source, report_warnings
from ltc_cli.ingest.keyframes import Reach, StillFrames, fixed_camera_after, known_pose
from ltc_cli.ingest.prefetch import Prefetch, Stopped, load_and_detect
from ltc_cli.ingest.session_row import keep_progress, kept_setup, now_iso, session_row, sessions_of
from ltc_cli.map.coverage import Coverage
from ltc_cli.map.model import SemanticMap
from ltc_cli.map.store import MapLock, load_map, save_map
from ltc_cli.pipeline.classes import ClassMapper
from ltc_cli.pipeline.frame_modeling import (BOUNDS_SENSOR_NOISE, FrameModel, excess_noise, in_map_classes,
                                            most_confident)
from ltc_cli.pipeline.mapper import Mapper
from ltc_cli.recordings.open import as_ingested, open_recording, select_frames
from ltc_cli.recordings.saved_detections import RECORDING_FIELD, detector_for
from ltc_cli.text import SkippedFrames
from ltc_cli.tools.calibration_file import calibration_settings, load_calibration
from ltc_cli.types import Recording

STAGES = ("load", "detect", "modeling", "association", "integration", "maintenance", "merge")


@dataclass
class IngestSummary:
    frames_done: int = 0
    frames_skipped: int = 0
    frames_already: int = 0
    frames_still: int = 0  # the camera had not moved since the last frame mapped (keyframes.py)
    detections: int = 0
    created: int = 0
    merged: int = 0
    removed: int = 0
    non_detections: int = 0
    objects: int = 0
    seconds: float = 0.0
    interrupted: bool = False
    session: int = 0
    visit: int = 1
    stage_seconds: dict = field(default_factory=dict)
    skipped_reasons: dict = field(default_factory=dict)  # frames skipped, by what their error said

    def as_dict(self) -> dict:
        return asdict(self)


def _ignore(message: str) -> None:
    pass


def _never() -> bool:
    return False


@dataclass
class RunOptions:
    """How a run goes (checkpoints, callbacks, threads), as opposed to what it maps."""

    checkpoint_every: int = 50
    strict: bool = False
    jobs: int = 1
    progress: Callable[[int], None] | None = None
    warn: Callable[[str], None] = _ignore
    should_stop: Callable[[], bool] = _never
    on_frame: Callable | None = None
    cluster: object | None = None  # a cluster.Cluster: stage 1 runs on its Dask workers

    def tick(self) -> None:
        if self.progress:
            self.progress(1)


@dataclass
class RecordingSetup:
    """One recording, made ready before the map is opened."""

    recording: Recording
    detector: object
    R_up: np.ndarray  # (3, 3): rotates the recording's world so that z is up
    floor_z: float | None  # in the z-up frame; None when not estimated
    depth_range: tuple[float, float]  # the recording's, within the settings' modeling range
    depth_noise: float | None = None  # the sensor's depth error std at 1 m, measured (frame_setup)
    reader: str | None = None  # as it was opened (recordings/open.as_ingested), for a Dask worker and the row
    reader_options: dict | None = None

    @property
    def T_up(self) -> np.ndarray:
        T = np.eye(4)
        T[:3, :3] = self.R_up
        return T


@dataclass
class Plan:
    """Everything an ingest decides before it touches the map."""

    settings: dict  # the effective settings (the caller's config with the calibration applied)
    calibration: dict | None
    setups: list[RecordingSetup]
    metric: object
    policy: object
    revisit: bool = False
    frames: slice | None = None  # --frames: the range of every recording's frames mapped (None: all)


def frame_key(identity: str, frame: str, visit: int) -> str:
    """The map's key of a frame; a first visit keeps the plain key that maps made before
    ``--revisit`` hold, so they resume and skip as before."""
    return f"{identity}/{frame}" if visit <= 1 else f"{identity}@{visit}/{frame}"


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
    revisit: bool = False,
    cluster=None,
    frames: slice | None = None,
) -> IngestSummary:
    """Ingest recordings into the map at ``map_path`` (created when it does not exist).

    Frames already in the map (by recording identity and frame id) are skipped, so re-running an
    interrupted ingest resumes it, and re-running a finished one changes nothing. ``revisit`` maps
    the recordings again as a new session, and resumes such a session when it was interrupted.
    ``jobs`` > 1 loads and detects frames ahead in that many threads; the map is the same (module
    docstring). ``cluster`` (a :class:`ltc_cli.ingest.cluster.Cluster`) runs loading, detection and
    object modeling on Dask workers instead (``jobs`` is then not used); the map is the same.
    ``frames`` maps that range of each recording's frames (recordings/open.frame_range); a range
    is its own session, resumed only by the same range. ``config`` is checked against the settings
    schema and never written into.
    """
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise ConfigError(f"jobs must be an integer >= 1, not {jobs!r}")
    t_start = time.perf_counter()
    map_path = Path(map_path)
    opts = RunOptions(checkpoint_every=checkpoint_every, strict=strict, jobs=jobs, progress=progress,
                      warn=warn or _ignore, should_stop=should_stop or _never, on_frame=on_frame,
                      cluster=cluster)
    settings = settings_from(config, *([calibration_settings(calibration)] if calibration is not None else []))
    if settings["detector"].get("save_to") is not None:  # Dask workers write there too, from their own folder
        settings["detector"]["save_to"] = str(Path(settings["detector"]["save_to"]).absolute())
    # Everything that can be checked before the map is touched is checked first.
    # A recording the map has read before is read the same way (its session row keeps the reader
    # and options), so a revisit of a plain folder needs no -r again; options given win.
    sessions = sessions_of(map_path)
    how = [as_ingested(p, sessions, reader, reader_options) for p in recording_paths]
    recordings = [open_recording(p, *h) for p, h in zip(recording_paths, how)]
    kept = [kept_setup(rec, *h, sessions) for rec, h in zip(recordings, how)]
    plan = _plan(recordings, settings, calibration, revisit, opts.warn, frames, kept)
    for setup, (r_name, r_opts) in zip(plan.setups, how):
        setup.reader, setup.reader_options = r_name, r_opts

    lock = MapLock(map_path).acquire()
    try:
        if map_path.exists():
            smap = load_map(map_path)
        else:
            first = plan.setups[0]
            classes = settings["map"]["classes"] or first.recording.classes or first.detector.classes
            if not classes:
                raise ConfigError("no class list: give map.classes, or a recording with classes")
            smap = SemanticMap.new(classes)
            smap.created = now_iso()
            smap.up_rotation = first.R_up
        summary = _run(smap, map_path, plan, opts)
    finally:
        lock.release()
    summary.seconds = time.perf_counter() - t_start
    return summary


def _plan(recordings: list[Recording], settings: dict, calibration, revisit: bool, warn=None,
          frames: slice | None = None, kept: list | None = None) -> Plan:
    """Plugins and per-recording set-up (up axis, floor, depth range), before the map is opened.

    The set-up is measured on the whole recording whatever the range ``frames`` mapped: measured on
    a range's own frames, tum-fr1-rpy's two halves were levelled 1.3 degrees apart (and the floor
    and depth error differed), so one recording's sessions were not in one map frame. A recording
    the map has read before takes the set-up it had then (``kept``, session_row.kept_setup)."""
    metric = plugins.get("metrics", settings["association"]["metric"]).factory(settings["association"])
    policy = plugins.get("policies", settings["maintenance"]["policy"]).factory(settings["maintenance"])
    save_to = settings["detector"].get("save_to")
    if save_to is not None and len(recordings) > 1 and RECORDING_FIELD not in save_to:
        raise ConfigError("detector.save_to takes one recording per folder (their frames' names may collide): "
                          f"put {RECORDING_FIELD} in it, which names each recording's folder")
    chosen = [select_frames(rec, frames) for rec in recordings]
    detectors = [detector_for(rec, settings["detector"]) for rec in chosen]
    m_cfg = settings["modeling"]
    setups = []
    for rec, part, det, before in zip(recordings, chosen, detectors, kept or [None] * len(recordings)):
        R_up, floor_z, depth_noise = before or frame_setup_for(rec, warn=warn)
        if warn is not None and m_cfg["depth_noise"] == "auto" and excess_noise(depth_noise) > 0:
            warn(f"{rec.path}: the depth error measured on its frames is {depth_noise:.3f} m at 1 m, over the "
                 f"{BOUNDS_SENSOR_NOISE} the size rules hold: they allow for it (a number in modeling.depth_noise "
                 f"overrides the measure)")
        lo, hi = rec.depth_range or (m_cfg["min_depth"], m_cfg["max_depth"])
        depth_range = (max(lo, m_cfg["min_depth"]), min(hi, m_cfg["max_depth"]))
        setups.append(RecordingSetup(part, det, R_up, floor_z, depth_range, depth_noise))
    return Plan(settings, calibration, setups, metric, policy, revisit, frames)


def _still_frame(smap: SemanticMap, key: str, summary: IngestSummary, row: dict) -> None:
    """A still camera's frame: done (a re-run skips it), counted, not mapped."""
    smap.frame_keys.add(key)
    summary.frames_still += 1
    row["frames_still"] = int(row.get("frames_still") or 0) + 1


def _run(smap: SemanticMap, map_path: Path, plan: Plan, opts: RunOptions) -> IngestSummary:
    n_sessions = len(smap.sessions)
    session, row = session_row(smap, plan)
    resumed = len(smap.sessions) == n_sessions
    mapper = Mapper(smap, plan.settings, plan.metric, plan.policy, session=session)
    summary = IngestSummary(session=session, visit=row["visit"])
    skips = SkippedFrames(opts.warn)
    stage = {k: 0.0 for k in STAGES}
    since_commit = 0
    completes = False
    max_dets = plan.settings["modeling"]["max_detections"]
    error: BaseException | None = None
    ahead: Prefetch | None = None
    still = StillFrames.resumed(plan.settings["frames"], len(plan.setups), row.get("still_refs") or "")
    cover = Coverage.resumed(row.get("coverage") or "", plan.settings["maintenance"]["ray_step"], row["frames_done"])
    try:
        for r, setup in enumerate(plan.setups):
            rec, det = setup.recording, setup.detector
            mapper_classes = ClassMapper(det.classes, smap.classes, plan.settings["integration"]["unassigned_score"])
            T_up = setup.T_up
            keys = [frame_key(rec.identity, ref.key, summary.visit) for ref in rec.frames]
            if opts.cluster is not None:
                ahead = opts.cluster.ahead(setup, plan, smap.classes, keys, smap.frame_keys, opts.should_stop,
                                           keep=still.judge_ahead(r))
            elif opts.jobs > 1:
                ahead = Prefetch(rec.frames, keys, smap.frame_keys, det, opts.jobs, keep=still.judge_ahead(r))
            fetch = ahead.take if ahead is not None else load_and_detect(
                det, keep=lambda f, r=r: not still.still(r, f.T_world_camera))
            warned: set = set()  # once-keys of this recording's frame warnings already reported
            reach, n_still, n_already = Reach(), 0, 0  # for the warning of a camera fixed in place
            for ref, key in zip(rec.frames, keys):
                if opts.should_stop():
                    summary.interrupted = True
                    break
                if key in smap.frame_keys:
                    summary.frames_already += 1
                    n_already += 1
                    opts.tick()
                    continue
                T_known = known_pose(ref)
                if T_known is not None:
                    reach.add(T_known)
                if T_known is not None and still.still(r, T_known):  # done, not loaded
                    _still_frame(smap, key, summary, row)
                    n_still += 1
                    opts.tick()
                    continue
                try:
                    frame, dets, t0, t1, t2 = fetch(ref)
                    if dets is None and not still.still(r, frame.T_world_camera):
                        # The look-ahead judged it still by a frame kept there and not mapped here.
                        td = time.perf_counter()
                        dets = ahead.detect_now(frame)
                        t2 += time.perf_counter() - td
                except Stopped:  # asked to stop while a Dask cluster had the frame
                    summary.interrupted = True
                    break
                except FrameError as exc:
                    if opts.strict:
                        raise
                    skips.skip(ref.key, exc)
                    summary.frames_skipped += 1
                    row["frames_skipped"] += 1
                    opts.tick()
                    continue
                report_warnings(frame, warned, opts.strict, opts.warn)
                stage["load"] += t1 - t0
                if T_known is None:
                    reach.add(frame.T_world_camera)
                if still.still(r, frame.T_world_camera):  # done, not mapped (nor detected)
                    _still_frame(smap, key, summary, row)
                    n_still += 1
                    opts.tick()
                    continue
                stage["detect"] += t2 - t1
                if not isinstance(dets, FrameModel) and len(dets) > max_dets:
                    opts.warn(f"{detections_source(det, frame)}: {len(dets)} detections in one frame, more than "
                              f"modeling.max_detections ({max_dets}); kept the {max_dets} most confident")
                    dets = most_confident(dets, max_dets)
                stage1 = dets if isinstance(dets, FrameModel) else None  # made by a Dask worker
                masks, vectors = in_map_classes(dets, mapper_classes) if stage1 is None else ([], [])
                T_map_camera = T_up @ frame.T_world_camera
                res = mapper.process_frame(ref.index, key, masks, vectors, frame.depth_m, T_map_camera,
                                           frame.intrinsics, setup.depth_range, floor_z=setup.floor_z, stage1=stage1,
                                           depth_noise=setup.depth_noise)
                cover.add(frame.depth_m, T_map_camera, frame.intrinsics, setup.depth_range)
                stage["modeling"] += stage1.seconds if stage1 is not None else 0.0
                for k, v in res.timings.items():
                    stage[k] += v
                smap.frame_keys.add(key)
                still.mapped(r, frame.T_world_camera)
                summary.frames_done += 1
                row["frames_done"] += 1
                summary.detections += res.detections
                summary.created += res.created
                summary.merged += res.merged
                summary.removed += res.removed
                summary.non_detections += res.non_detections
                since_commit += 1
                if opts.on_frame:
                    opts.on_frame(summary)
                opts.tick()
                if opts.checkpoint_every and since_commit >= opts.checkpoint_every:
                    keep_progress(row, still, cover)
                    save_map(smap, map_path)
                    since_commit = 0
            if ahead is not None:
                ahead.close()
                ahead = None
            if summary.interrupted:
                break
            line = fixed_camera_after(rec.frames, n_still, reach, n_already, resumed, plan.settings["frames"])
            if line:
                opts.warn(f"{rec.path}: {line}")
        # A resumed session whose frames were all committed before the kill still ends here: it is
        # finished (pruned, marked complete) exactly as an uninterrupted run would have finished it.
        completes = summary.frames_done > 0 or (resumed and not summary.interrupted)
        k = plan.settings["maintenance"]["min_detections"]
        share = plan.settings["maintenance"]["min_detection_share"]
        m_cfg = plan.settings["maintenance"]
        if not summary.interrupted and completes and (k > 1 or share or m_cfg["absent_after_views"]
                                                      or m_cfg["min_detection_views"]):
            summary.removed += mapper.prune_unconfirmed(k, -1, "end of session", share)
    except BaseException as exc:  # commit what is done, then let the error go on
        error = exc
        if ahead is not None:  # stop the look-ahead before committing; its results are dropped
            ahead.close()
    row["status"] = "interrupted" if (summary.interrupted or error is not None) else "complete"
    row["finished"] = now_iso()
    keep_progress(row, still, cover)
    # A run that mapped no frame leaves the file as it was (and creates none): bad input never
    # changes a map.
    if summary.frames_done > 0 or (completes and error is None):
        save_map(smap, map_path)
    summary.objects = len(smap.active_rows())
    summary.stage_seconds = stage
    summary.skipped_reasons = dict(skips.counts)
    if error is not None:
        raise error
    return summary


__all__ = ["ingest", "open_recording", "IngestSummary", "LtcError", "load_calibration", "frame_key",
           "RunOptions", "RecordingSetup", "Plan"]

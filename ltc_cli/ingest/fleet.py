"""``ltc ingest-many``: the recordings of a manifest into their maps, one writer per map.

Each map has one writer, a thread of this process that holds the map's lock and ingests the map's
recordings one after another, each as one session, in time order: exactly the sequence of
``ltc ingest REC --map MAP`` runs it replaces, so the maps are the same. Writers of different maps
run at once (``writers`` of them), sharing the Dask cluster when one is given: the workers do the
loading, detection and modeling of every writer's frames, and each writer only associates,
integrates, maintains and commits. A recording that fails is reported in its row and the writer
goes on with the map's next one; a stop request (Ctrl-C, SIGTERM) stops every writer after its
current frame, committed, and the recordings not started are reported as such.
"""

from __future__ import annotations

import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Callable

from ltc_cli import plugins
from ltc_cli.errors import LtcError
from ltc_cli.ingest.manifest import MapJob, load_manifest
from ltc_cli.ingest.session import IngestSummary, ingest
from ltc_cli.recordings.open import frames_text, open_recording, select_frames


@dataclass
class Outcome:
    """One recording of the manifest: status ok / failed / interrupted / not run."""

    map_name: str
    map_path: str
    recording: str
    time: str
    status: str
    summary: IngestSummary | None = None
    error: str = ""
    objects: int | None = None  # in the map after this recording
    seconds: float = 0.0
    frames: str = ""  # the range of its frames (the manifest's frames), "" for all


def _ignore(*_args) -> None:
    pass


def _never() -> bool:
    return False


def _write_map(job: MapJob, cluster, options: dict, should_stop, warn, progress) -> list[Outcome]:
    """The writer of one map: its recordings in order; a failure is recorded and the next goes on."""
    out = []
    for rec in job.recordings:
        row = Outcome(job.name, str(job.path), str(rec.path), rec.time.isoformat() if rec.time else "", "not run",
                      frames=frames_text(rec.frames))
        out.append(row)
        if should_stop():
            continue
        t0 = time.perf_counter()
        try:
            s = ingest([rec.path], job.path, job.config, reader=rec.reader, reader_options=rec.options,
                       frames=rec.frames, calibration=job.calibration,
                       cluster=cluster, should_stop=should_stop, warn=lambda m, r=rec.path: warn(f"{r}: {m}"),
                       progress=progress, **options)
            row.summary, row.objects = s, s.objects
            row.status = "interrupted" if s.interrupted else "ok"
        except LtcError as exc:
            row.status, row.error = "failed", str(exc)
        except Exception as exc:  # a bug or a dead cluster: still only this recording's failure
            row.status, row.error = "failed", f"{rec.path}: {type(exc).__name__}: {exc}"
        row.seconds = time.perf_counter() - t0
    return out


def ingest_many(
    manifest,
    *,
    cluster=None,
    writers: int = 4,
    checkpoint_every: int = 50,
    strict: bool = False,
    should_stop: Callable[[], bool] | None = None,
    warn: Callable[[str], None] | None = None,
    progress: Callable[[int], None] | None = None,
) -> list[Outcome]:
    """Ingest every recording of ``manifest`` into its map; one Outcome per recording, maps in the
    manifest's order and each map's recordings in the order they were ingested. ``warn`` and
    ``progress`` are called from the writer threads, one call at a time."""
    jobs = load_manifest(manifest)
    plugins.registry("detectors")  # load the plugins once, before the writer threads ask for them
    if writers < 1:
        raise LtcError(f"writers must be >= 1, not {writers}")
    lock = threading.Lock()

    def serial(fn):
        def call(*args):
            with lock:
                fn(*args)
        return call

    options = {"checkpoint_every": checkpoint_every, "strict": strict}
    stop = should_stop or _never
    with ThreadPoolExecutor(max_workers=min(writers, len(jobs)), thread_name_prefix="ltc-writer") as pool:
        futures = [pool.submit(_write_map, job, cluster, options, stop, serial(warn or _ignore),
                               serial(progress) if progress else None) for job in jobs]
        return [row for fut in futures for row in fut.result()]


def summary_table(rows: list[Outcome]) -> list[str]:
    """The summary of an ingest-many run: one line per recording, then the errors in full."""
    lines = [f"{'map':<16} {'recording':<28} {'status':<11} {'frames':>7} {'skip':>5} {'still':>5} {'had':>5} "
             f"{'new':>5} {'gone':>5} {'objects':>7} {'s':>7}"]
    for r in rows:
        s = r.summary
        nums = (f"{s.frames_done:>7} {s.frames_skipped:>5} {s.frames_still:>5} {s.frames_already:>5} {s.created:>5} "
                f"{s.removed:>5} " if s is not None else f"{'-':>7} {'-':>5} {'-':>5} {'-':>5} {'-':>5} {'-':>5} ")
        objects = "-" if r.objects is None else str(r.objects)
        label = f"{r.recording} [{r.frames}]" if r.frames else r.recording
        lines.append(f"{r.map_name[:16]:<16} {_tail(label, 28):<28} {r.status:<11} {nums}{objects:>7} "
                     f"{r.seconds:>7.1f}")
    lines += [f"failed: {r.error}" for r in rows if r.status == "failed"]
    return lines


def _tail(text: str, width: int) -> str:
    return text if len(text) <= width else "..." + text[-(width - 3):]


def summary_line(rows: list[Outcome]) -> str:
    n = {k: sum(r.status == k for r in rows) for k in ("ok", "failed", "interrupted", "not run")}
    maps = len({r.map_path for r in rows})
    frames = sum(r.summary.frames_done for r in rows if r.summary is not None)
    parts = [f"{n['ok']} ok", f"{n['failed']} failed"] + [f"{n[k]} {k}" for k in ("interrupted", "not run") if n[k]]
    return f"{len(rows)} recordings into {maps} maps: {', '.join(parts)}; {frames} frames ingested"


def manifest_frames(manifest) -> int:
    """Frames of the manifest's recordings that can be opened (for a progress bar)."""
    total = 0
    for job in load_manifest(manifest):
        for rec in job.recordings:
            try:
                total += len(select_frames(open_recording(rec.path, rec.reader, rec.options), rec.frames))
            except LtcError:
                pass  # reported as that recording's failure when its turn comes
    return total

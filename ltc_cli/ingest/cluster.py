"""Dask distributed for ``ltc ingest --dask`` and ``ltc ingest-many --dask`` (the extra ``ltc[dask]``).

Stage 1 (loading, detection, object modeling) of each frame runs on the workers as a
:class:`remote.FrameTask`; the process that holds the map's lock takes the results in frame order
through the ordinary look-ahead (:class:`Prefetch` over the client's ``concurrent.futures``
executor) and applies stages 2-4 itself. So the map is the one a single process makes:

- each frame's result is taken once, at its turn; a task that ran twice (its worker died after
  starting it, and the scheduler gave it to another) is pure, and only one result reaches the
  writer;
- a worker that dies takes its running tasks with it and the scheduler runs them elsewhere
  (``distributed.scheduler.allowed-failures`` times, 3 by default; then the frame's error stops the
  ingest, with the frames before it committed);
- a bad frame comes back as a value and is skipped (or stops ``--strict``) at its turn, as locally.
"""

from __future__ import annotations

import logging
import os
import signal
import threading
from concurrent.futures import TimeoutError as FutureTimeout  # not yet the builtin one in 3.10
from contextlib import contextmanager

from ltc_cli.errors import LtcError
from ltc_cli.ingest.prefetch import Prefetch, Stopped
from ltc_cli.ingest.remote import FrameTask, RecordingJob, unpack

DEFAULT_BATCH = 4  # frames per task (benchmarks/bench_fleet.py)
STOP_POLL = 0.25  # seconds between looks at the stop request while a frame is awaited
MISSING = "--dask needs the optional extra ltc[dask]: pip install 'ltc[dask]'"


class DaskError(LtcError):
    """Dask is not installed, the scheduler cannot be reached, or the cluster failed a frame."""


def _distributed():
    try:
        import distributed
    except ImportError:
        raise DaskError(MISSING) from None
    return distributed


class RemoteAhead(Prefetch):
    """The look-ahead of one recording on a Dask cluster; ``take`` returns what
    ``load_and_detect`` does, with the frame's stage 1 in place of its detections."""

    def __init__(self, refs, keys, done, job: RecordingJob, pool, lookahead: int, batch: int, should_stop, keep=None):
        super().__init__(refs, keys, done, None, 1, lookahead, pool=pool, task=FrameTask(job), batch=batch, keep=keep)
        self.job = job
        self.should_stop = should_stop

    def wait(self, fut):
        # A cluster may take any time (its workers gone, the scheduler waiting for new ones): a
        # stop request (Ctrl-C, SIGTERM) ends the wait, and the run commits what it has mapped.
        while True:
            try:
                return fut.result(timeout=STOP_POLL)
            except FutureTimeout:
                if self.should_stop():
                    raise Stopped() from None

    def take(self, ref):
        try:
            result = super().take(ref)
        except (LtcError, Stopped):
            raise
        except Exception as exc:  # e.g. KilledWorker after too many deaths, a lost scheduler
            raise DaskError(f"the Dask cluster failed frame {ref.key} ({type(exc).__name__}: {exc})",
                            self.job.path) from exc
        return unpack(result, self.job, ref.index)


class Cluster:
    """A Dask client (and the LocalCluster behind it, for ``local``), as ingest uses it.

    ``batch`` frames go in one task: Dask costs a few ms of scheduler and client CPU per task
    (docs/fleet.md), which batches divide. Twice as many frames as the cluster has threads times
    ``batch`` are in flight, so no worker waits for the writer to ask.
    """

    def __init__(self, client, local=None, batch: int = DEFAULT_BATCH):
        if batch < 1:
            raise DaskError(f"frames per Dask task must be >= 1, not {batch}")
        self.client = client
        self.local = local
        self.batch = batch
        self.executor = client.get_executor(pure=False)

    def threads(self) -> int:
        """Worker threads in the cluster now (at least 1)."""
        return max(1, sum(self.client.nthreads().values()))

    def ahead(self, setup, plan, classes: list[str], keys: list[str], done, should_stop, keep=None) -> RemoteAhead:
        """The look-ahead of one recording (``setup``: a session.RecordingSetup) for a map whose
        class list is ``classes``; ``keep``: which frames a still camera's are, judged by the poses
        the reader knows before loading (Prefetch), so that the workers are never sent them."""
        rec = setup.recording
        job = RecordingJob(str(rec.path), setup.reader, setup.reader_options, rec.identity, plan.settings,
                           tuple(classes), setup.T_up, setup.floor_z, tuple(setup.depth_range),
                           setup.depth_noise, plan.frames)
        return RemoteAhead(rec.frames, keys, done, job, self.executor, 2 * self.batch * self.threads(), self.batch,
                           should_stop, keep)

    def close(self) -> None:
        self.client.close()
        if self.local is not None:
            self.local.close()

    def __enter__(self) -> "Cluster":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def parse_spec(spec: str):
    """``local`` -> ("local", one worker per core); ``local:N`` -> ("local", N); else ("address", spec)."""
    if spec == "local" or spec.startswith("local:"):
        n = spec[len("local:"):] if ":" in spec else str(os.cpu_count() or 1)
        if not n.isdigit() or int(n) < 1:
            raise DaskError(f"--dask {spec}: expected local, local:N (N >= 1 workers) or a scheduler address")
        return "local", int(n)
    return "address", spec


@contextmanager
def _sigint_ignored():
    """SIGINT ignored while local workers start: they inherit that, so a Ctrl-C at the terminal (sent
    to the whole process group) stops only the writer, which commits and then closes them."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)


def open_cluster(spec: str, timeout: float = 10.0, batch: int = DEFAULT_BATCH) -> Cluster:
    """``local`` / ``local:N``: a LocalCluster of worker processes, one thread each, on this
    machine; anything else: the address of a running scheduler (``tcp://HOST:8786``)."""
    kind, value = parse_spec(spec)
    distributed = _distributed()
    if kind == "local":
        import dask

        # Workers log only what is critical: their errors reach the writer anyway (a frame that
        # fails, a worker that dies and is replaced), and closing the cluster makes them log
        # harmless tracebacks (a heartbeat to a scheduler that just closed).
        # The workers' statistical profiler samples every thread's stack every 10 ms: measured, it
        # costs ~15% of a worker's CPU here (docs/fleet.md); ltc does not use it.
        try:
            with _sigint_ignored(), dask.config.set({"distributed.worker.profile.enabled": False}):
                local = distributed.LocalCluster(n_workers=value, threads_per_worker=1, processes=True,
                                                 dashboard_address=":0", silence_logs=logging.CRITICAL)
        except Exception as exc:  # cannot start processes, no ports, ...
            raise DaskError(f"cannot start a local Dask cluster ({type(exc).__name__}: {exc})") from exc
        return Cluster(distributed.Client(local), local, batch)
    try:
        client = distributed.Client(value, timeout=timeout)
    except (OSError, ValueError) as exc:  # refused, unreachable, timed out (TimeoutError is an OSError)
        raise DaskError(f"cannot reach the Dask scheduler at {value} ({type(exc).__name__}: {exc})") from None
    return Cluster(client, batch=batch)


@contextmanager
def cluster_for(spec: str | None, batch: int = DEFAULT_BATCH):
    """``with cluster_for(spec) as cluster``: None without a spec, else the open :class:`Cluster`,
    closed at the end (a ``local`` one with its workers)."""
    if not spec:
        yield None
        return
    with open_cluster(spec, batch=batch) as cluster:
        yield cluster

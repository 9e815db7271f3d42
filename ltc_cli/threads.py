"""How many threads the numerical libraries may use while ltc maps (issue 11).

Two pools compete for the cores besides ltc's own ``--jobs`` threads:

- OpenBLAS: its worker threads busy-wait between the small matrix products of the YOLO masks and
  the stages (3x3 rotations, (32, 160x160) mask protos), which cost +45 % CPU on a real-detector
  ingest and bought nothing. While an ingest runs, BLAS gets one thread (threadpoolctl).
- onnxruntime's intra-op pool: the ONNX detectors' ``threads`` option defaults to
  :func:`threads_per_job`, the cores divided among the ``--jobs`` threads that detect at once.
- OpenCV's own pool: it split the YOLO letterbox's filter over both cores, which cost 0.5 ms of
  CPU per frame in its workers for a 0.6 ms task; the ingest's parallelism is ``--jobs``. While an
  ingest runs, OpenCV gets one thread too.
"""

from __future__ import annotations

import os
from contextlib import contextmanager

_jobs = 1  # the --jobs of the ingest in progress (1 outside one)


def cores() -> int:
    """The cores this process may run on (its affinity mask, not the machine's count)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - macOS, Windows
        return max(1, os.cpu_count() or 1)


def threads_per_job() -> int:
    """Intra-op threads for one detector call: the cores shared among the jobs detecting at once."""
    return max(1, cores() // _jobs)


@contextmanager
def mapping_threads(jobs: int = 1):
    """While mapping with ``jobs`` detecting threads: one BLAS thread, and detectors built inside
    see :func:`threads_per_job` = cores // jobs."""
    global _jobs
    # threadpoolctl limits the BLAS libraries already loaded, and numpy, scipy and OpenCV each
    # bring their own OpenBLAS: all three are loaded first (a mapping run needs them anyway). In
    # the CLI, the OPENBLAS_NUM_THREADS default that ltc_cli.cli.main sets covers any other. These
    # imports are here so that the commands that map nothing do not pay for them.
    import cv2
    import numpy  # noqa: F401
    import scipy.spatial.transform  # noqa: F401
    from threadpoolctl import threadpool_limits

    before, cv_before = _jobs, cv2.getNumThreads()
    _jobs = max(1, int(jobs))
    cv2.setNumThreads(1)
    try:
        with threadpool_limits(limits=1, user_api="blas"):
            yield
    finally:
        _jobs = before
        cv2.setNumThreads(cv_before)

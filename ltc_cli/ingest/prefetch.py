"""Look-ahead: load and detect the next frames of a recording in a thread pool while the mapper
works on the current one. Results are taken in recording order, so the map does not depend on it.
"""

from __future__ import annotations

import threading
import time
from concurrent.futures import ThreadPoolExecutor


def load_and_detect(det, lock=None):
    """fetch(ref) -> (frame, detections, t0, t1, t2): load the frame (t0 -> t1), then detect (t1 ->
    t2); FrameError propagates. With a lock, ``detect`` runs under it and the wait is not timed."""

    # Readers may leave the colour image to be decoded on first use (Frame.rgb): a detector that
    # says it needs no colour (``needs_rgb = False``, like ``recorded``) never decodes it; for the
    # others it is decoded here, in the loading time and outside the detector's lock.
    needs_rgb = getattr(det, "needs_rgb", True)

    def fetch(ref):
        t0 = time.perf_counter()
        frame = ref.load()
        if needs_rgb:
            frame.rgb  # noqa: B018  (the read decodes it)
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


class Prefetch:
    """Loads and detects the frames of one recording ahead of the mapper in a thread pool.

    ``take(ref)`` returns what ``load_and_detect`` returns for ``ref`` (or raises what it raised),
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
        self.fetch = load_and_detect(det, lock)
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

"""Look-ahead: load and detect the next frames of a recording in a thread pool while the mapper
works on the current one. Results are taken in recording order, so the map does not depend on it.
"""

from __future__ import annotations

import threading
import time
from concurrent.futures import ThreadPoolExecutor

from ltc_cli.ingest.keyframes import known_pose


def load_and_detect(det, lock=None, keep=None):
    """fetch(ref) -> (frame, detections, t0, t1, t2): load the frame (t0 -> t1), then detect (t1 ->
    t2); FrameError propagates. With a lock, ``detect`` runs under it and the wait is not timed.
    ``keep(frame) -> bool``: False leaves a frame undetected (detections None, t2 = t1): a still
    camera's frame, which the session does not map (ingest/keyframes.py)."""
    detect = _timed_detect(det, lock)

    def fetch(ref):
        frame, t0, t1 = _load(ref)
        if keep is not None and not keep(frame):
            return frame, None, t0, t1, t1
        dets, decode, seconds = detect(frame)
        return frame, dets, t0, t1 + decode, t1 + decode + seconds

    return fetch


def _load(ref):
    """(frame, t0, t1): the frame loaded, colour left undecoded (a frame not kept never needs it)."""
    t0 = time.perf_counter()
    frame = ref.load()
    return frame, t0, time.perf_counter()


def _timed_detect(det, lock):
    """detect(frame) -> (detections, seconds decoding colour, seconds detecting); under ``lock``
    when given (its wait not timed). The colour decoding counts as loading."""
    # Readers may leave the colour image to be decoded on first use (Frame.rgb): a detector that
    # says it needs no colour (``needs_rgb = False``, like ``recorded``) never decodes it; for the
    # others it is decoded here, outside the detector's lock.
    needs_rgb = getattr(det, "needs_rgb", True)

    def detect(frame):
        t0 = time.perf_counter()
        if needs_rgb:
            frame.rgb  # noqa: B018  (the read decodes it)
        t1 = time.perf_counter()
        if lock is None:
            dets = det.detect(frame)
            return dets, t1 - t0, time.perf_counter() - t1
        with lock:
            td = time.perf_counter()
            dets = det.detect(frame)
            return dets, t1 - t0, time.perf_counter() - td
    return detect


class Stopped(Exception):
    """The caller asked to stop while a frame's result was awaited (see Prefetch.wait)."""


class Prefetch:
    """Loads and detects the frames of one recording ahead of the mapper in a thread pool.

    ``take(ref)`` returns what ``load_and_detect`` returns for ``ref`` (or raises what it raised),
    for refs asked in recording order; frames whose key is in ``done`` when they come into the
    look-ahead window are never loaded. Everything is submitted from the calling thread, so ``done``
    (the map's frame keys) is only read there.

    ``keep(T_world_camera) -> bool`` (ingest/keyframes.py ``judge_ahead``) leaves a still camera's
    frames undetected, judged in recording order (never out of it: the judgement of a frame depends
    on those before it). When every ref knows its pose (``FrameRef.pose``), the frames are judged
    as they come into the window, by the calling thread, and those not kept are never submitted:
    not loaded, nor sent to a Dask cluster. Otherwise (local threads only) it is two steps: the
    threads load the frames, the calling thread judges each loaded frame, and only the frames kept
    are detected, in the threads; a frame not kept comes back with detections None, having cost
    its loading only, as without look-ahead.

    ``pool`` and ``task`` replace the thread pool and ``load_and_detect``: any
    ``concurrent.futures.Executor`` (a Dask client's ``get_executor()``) and a callable
    ``task([(position, key), ...]) -> [result, ...]`` it can run (remote.FrameTask), given up to
    ``batch`` frames at a time (fewer, larger tasks: the overhead per task is paid once per batch).
    The pool then belongs to the caller: ``close`` cancels what is pending and leaves it open.
    """

    def __init__(self, refs, keys, done, det, jobs: int, lookahead: int | None = None, pool=None, task=None,
                 batch: int = 1, keep=None):
        self.refs = list(refs)
        self.keys = list(keys)
        self.done = done
        self.position = {id(r): i for i, r in enumerate(self.refs)}
        self.by_pose = keep is not None and all(getattr(r, "pose", None) is not None for r in self.refs)
        self.keep = keep if (task is None or self.by_pose) else None
        self.two_step = self.keep is not None and not self.by_pose
        self.judged: dict = {}  # position -> (frame, detection future or None, t0, t1) or the load's error
        if task is None:
            lock = None if getattr(det, "thread_safe", False) else threading.Lock()
            self.detect = _timed_detect(det, lock)
            if self.two_step:
                task = lambda items: [_load(self.refs[j]) for j, _ in items]  # noqa: E731
            else:
                fetch = load_and_detect(det, lock)
                task = lambda items: [fetch(self.refs[j]) for j, _ in items]  # noqa: E731
        self.task = task
        self.batch = max(1, batch)
        self.lookahead = max(self.batch, lookahead or 2 * jobs)
        self.own_pool = pool is None
        self.pool = ThreadPoolExecutor(max_workers=jobs, thread_name_prefix="ltc-detect") if pool is None else pool
        self.pending: dict = {}  # position -> (Future of its batch, its place in the batch)
        self.next = 0  # the next position to consider for submission

    def _submit(self, items) -> None:
        fut = self.pool.submit(self.task, items)
        for k, (j, _) in enumerate(items):
            self.pending[j] = (fut, k)

    def _drop(self, j) -> None:
        fut, _ = self.pending.pop(j)
        if all(f is not fut for f, _ in self.pending.values()):  # no frame of its batch is wanted
            fut.cancel()

    def take(self, ref):
        i = self.position[id(ref)]
        for j in [j for j in self.pending if j < i]:  # frames the caller skipped after all
            self._drop(j)
        for j in [j for j in self.judged if j < i]:
            judged = self.judged.pop(j)
            if isinstance(judged, tuple) and judged[1] is not None:
                judged[1].cancel()
        while self.next < len(self.refs) and (self.next <= i or self._held() < self.lookahead):
            items = []
            while self.next < len(self.refs) and len(items) < self.batch:
                j = self.next
                self.next += 1
                if self.keys[j] in self.done or (self.by_pose and not self._kept(self.refs[j])):
                    continue
                items.append((j, self.refs[j].key))
            if items:
                self._submit(items)
        if i not in self.pending and i not in self.judged:  # not submitted (its key was already in the map then)
            self._submit([(i, ref.key)])
        if not self.two_step:
            fut, k = self.pending.pop(i)
            return self.wait(fut)[k]
        self._judge(i)
        judged = self.judged.pop(i)
        if isinstance(judged, BaseException):
            raise judged
        frame, det_fut, t0, t1 = judged
        if det_fut is None:
            return frame, None, t0, t1, t1
        dets, decode, seconds = self.wait(det_fut)
        return frame, dets, t0, t1 + decode, t1 + decode + seconds

    def _kept(self, ref) -> bool:
        """Judged by its pose as it comes into the window; a pose that cannot be read is kept (its
        load says why, at its turn)."""
        T = known_pose(ref)
        return T is None or self.keep(T)

    def _held(self) -> int:
        """Frames loading, or loaded and judged, ahead of the caller."""
        return len(self.pending) + len(self.judged)

    def _judge(self, i) -> None:
        """Judge the loaded frames in recording order: up to ``i`` (waiting for their loads), then
        on while the next one is loaded; submit the detection of each frame kept."""
        for j in sorted(self.pending):
            fut, k = self.pending[j]
            if j > i and not fut.done():
                break
            del self.pending[j]
            try:
                frame, t0, t1 = self.wait(fut)[k]
            except Stopped:
                raise
            except Exception as exc:  # noqa: BLE001  (a bad frame: raised again when taken)
                self.judged[j] = exc
                continue
            det_fut = self.pool.submit(self.detect, frame) if self.keep(frame.T_world_camera) else None
            self.judged[j] = (frame, det_fut, t0, t1)

    def detect_now(self, frame):
        """Detect one frame in the calling thread (under the detector's lock): a frame the look-ahead
        did not keep and the session maps after all."""
        dets, _, _ = self.detect(frame)
        return dets

    def wait(self, fut):
        """The result of a batch's future (a subclass may stop waiting: raise Stopped)."""
        return fut.result()

    def close(self) -> None:
        """Cancel the work not started, wait for the frames in flight, drop every result."""
        for fut, _ in self.pending.values():
            fut.cancel()
        for judged in self.judged.values():
            if isinstance(judged, tuple) and judged[1] is not None:
                judged[1].cancel()
        self.pending.clear()
        self.judged.clear()
        if self.own_pool:
            self.pool.shutdown(wait=True, cancel_futures=True)

"""Distributed ingest on Dask: frames per second with 1 and 2 workers, the scheduler's overhead per
frame, and the single writer's ceiling, with the real shared detector (YOLOv8n-seg fp32, onnxruntime,
one thread) on the real shared recording tum-fr1-rpy (232 frames of 640x480).

    python benchmarks/bench_fleet.py [--model PATH] [--data DIR] [--noop N]

Prints, each run into a fresh map:

- single process (``ltc ingest``, one thread): frames/s, the baseline;
- stage 1 alone, per frame (load + detect + model, what a worker does), and the bytes of its
  result on the wire (what travels instead of the masks and the full depth image);
- the writer alone: stages 2-4 and the commits fed from stage 1 results already made (an executor
  that hands them back at once): the ceiling of one map's writer, however many workers feed it;
- two writers (two maps) at once in one process, as ``ltc ingest-many`` runs them;
- ``--dask`` with 1 and 2 worker processes (one thread each) on this machine: frames/s, cluster
  start-up not included, and whether the map equals the single-process one;
- the scheduler overhead per frame: ``--noop`` tasks that return a result of the same size, through
  the same look-ahead on the 2-worker cluster: the round trip per frame, all of it overhead.

The machine has 2 cores (shared): with 2 workers and the writer they compete for them.
"""

from __future__ import annotations

import argparse
import os
import pickle
import sys
import tempfile
import time
from concurrent.futures import Future, ThreadPoolExecutor
from functools import partial
from pathlib import Path
from types import SimpleNamespace

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from ltc_cli.config import load_config  # noqa: E402
from ltc_cli.ingest.cluster import Cluster, open_cluster  # noqa: E402
from ltc_cli.ingest.prefetch import Prefetch  # noqa: E402
from ltc_cli.ingest.session import ingest  # noqa: E402
from ltc_cli.map.store import load_map  # noqa: E402

SHARED = ROOT.parent / "shared"


class InlinePool:
    """An executor that runs each task at once in this process and keeps its result: the first pass
    times stage 1 alone; later passes hand the kept results back (the writer alone)."""

    def __init__(self):
        self.results: dict = {}
        self.seconds = 0.0
        self.cpu = 0.0
        self.bytes: list[int] = []

    def submit(self, task, items):
        for item in items:
            if item not in self.results:
                t0, c0 = time.perf_counter(), time.process_time()
                res = task([item])[0]
                self.seconds += time.perf_counter() - t0
                self.cpu += time.process_time() - c0
                self.bytes.append(len(pickle.dumps(res, protocol=5)))
                self.results[item] = res
        fut = Future()
        fut.set_result([self.results[item] for item in items])
        return fut


class InlineCluster(Cluster):
    def __init__(self):  # no Dask client: the InlinePool stands for the workers
        self.executor = InlinePool()
        self.batch = 1

    def threads(self) -> int:
        return 1


def state(path):
    smap = load_map(path)
    cols = {k: v.copy() for k, v in smap.objects.columns().items()}
    events = [(e.session, e.frame, e.frame_key, e.kind, e.object_id, e.other_id) for e in smap.events]
    return cols, events


def same_map(a, b) -> bool:
    ca, ea = state(a)
    cb, eb = state(b)
    return ea == eb and all(np.array_equal(ca[k], cb[k]) for k in ca)


def noop(settings: dict, nbytes: int, items):
    """A task as large as a FrameTask (it carries the settings) whose results are as large as a
    frame's, doing nothing: its round trip is all overhead."""
    return [np.zeros(nbytes, np.uint8) for _ in items]


def noop_overhead(cluster: Cluster, settings: dict, n: int, nbytes: int, batch: int) -> tuple[float, float]:
    """(wall seconds, this process's CPU seconds) per frame of ``n`` no-op frames, ``batch`` per
    task, taken in order through the look-ahead that ingest uses."""
    refs = [SimpleNamespace(key=str(i)) for i in range(n)]
    ahead = Prefetch(refs, [r.key for r in refs], set(), None, 1, 2 * batch * cluster.threads(),
                     pool=cluster.executor, task=partial(noop, settings, nbytes), batch=batch)
    t0, c0 = time.perf_counter(), time.process_time()
    for r in refs:
        ahead.take(r)
    ahead.close()
    return (time.perf_counter() - t0) / n, (time.process_time() - c0) / n


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--model", default=str(SHARED / "models" / "yolov8n-seg_fp32.onnx"))
    ap.add_argument("--data", default=str(SHARED / "data" / "tum-fr1-rpy"))
    ap.add_argument("--noop", type=int, default=480, help="no-op frames for the scheduler overhead")
    ap.add_argument("--batch", type=int, default=4, help="frames per task of the --dask runs")
    args = ap.parse_args()
    if not Path(args.model).is_file() or not Path(args.data).is_dir():
        sys.exit("bench_fleet: needs the shared model and recording (../shared)")
    try:
        import distributed  # noqa: F401
    except ImportError:
        sys.exit("bench_fleet: needs the extra ltc[dask]")
    sets = ["detector.name=onnx-yolo-seg", f"detector.options.model={args.model}"]
    cfg = load_config(None, sets)
    rec = Path(args.data)
    print(f"{rec.name} with {Path(args.model).name} (onnxruntime, 1 thread per detector)")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        t0, c0 = time.perf_counter(), time.process_time()
        s = ingest([rec], tmp / "single.h5", cfg)
        single = s.frames_done / (time.perf_counter() - t0)
        n = s.frames_done
        print(f"  single process             {single:6.2f} frames/s  ({1000 / single:.0f} ms/frame wall, "
              f"{1000 * (time.process_time() - c0) / n:.0f} ms CPU; {n} frames)")

        inline = InlineCluster()
        ingest([rec], tmp / "inline.h5", cfg, cluster=inline)
        pool = inline.executor
        print(f"  stage 1 alone (a worker)   {n / pool.seconds:6.2f} frames/s  ({1000 * pool.seconds / n:.0f} ms/frame "
              f"wall, {1000 * pool.cpu / n:.0f} ms CPU); result {np.mean(pool.bytes) / 1e3:.1f} kB/frame on the "
              f"wire (the full depth image alone: {640 * 480 * 4 / 1e3:.0f} kB)")
        t0, c0 = time.perf_counter(), time.process_time()
        w = ingest([rec], tmp / "writer.h5", cfg, cluster=inline)
        writer = w.frames_done / (time.perf_counter() - t0)
        print(f"  writer alone (stages 2-4)  {writer:6.2f} frames/s  ({1000 / writer:.1f} ms/frame wall, "
              f"{1000 * (time.process_time() - c0) / n:.1f} ms CPU, commits included): one map's ceiling; "
              f"same map: {same_map(tmp / 'single.h5', tmp / 'writer.h5')}")

        t0 = time.perf_counter()
        with ThreadPoolExecutor(2) as writers:  # two maps, two writer threads of one process
            list(writers.map(lambda k: ingest([rec], tmp / f"writer{k}.h5", cfg, cluster=inline), (1, 2)))
        both = 2 * n / (time.perf_counter() - t0)
        print(f"  2 writers in one process   {both:6.2f} frames/s  (two maps at once, threads: they share one "
              f"interpreter lock)")

        nbytes = int(np.mean(pool.bytes))
        for workers in (1, 2):
            with open_cluster(f"local:{workers}", batch=args.batch) as cluster:  # as --dask local:N
                m = tmp / f"dask{workers}.h5"
                w0 = sum(cluster.client.run(time.process_time).values())
                t0, c0 = time.perf_counter(), time.process_time()
                d = ingest([rec], m, cfg, cluster=cluster)
                fps = d.frames_done / (time.perf_counter() - t0)
                here = (time.process_time() - c0) / n
                there = (sum(cluster.client.run(time.process_time).values()) - w0) / n
                print(f"  --dask, {workers} worker{'s' if workers > 1 else ' '}          {fps:6.2f} frames/s  "
                      f"({fps / single:.2f}x single; {args.batch} frames per task; model loading on the workers "
                      f"included); CPU per frame: workers {1000 * there:.0f} ms, writer + scheduler "
                      f"{1000 * here:.1f} ms; same map: {same_map(tmp / 'single.h5', m)}")
                if workers == 2:
                    for batch in (1, 4, 16):
                        wall, cpu = noop_overhead(cluster, cfg, args.noop, nbytes, batch)
                        print(f"  scheduler overhead, {batch:2d}/task {1000 * wall:5.2f} ms/frame wall, "
                              f"{1000 * cpu:.2f} ms/frame CPU in this process (client + scheduler; {args.noop} "
                              f"no-op frames of {nbytes / 1e3:.1f} kB, 2 workers)")


if __name__ == "__main__":
    main()

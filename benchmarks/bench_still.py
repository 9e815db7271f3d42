"""What judging a still camera's frames before reading them saves (issue 9, fifty-fifth round).

tum-fr1-rpy with the camera standing for 150 frames after frames 40, 120 and 200 (real_stops.py:
682 frames, 457 still), ingested with the reader's poses known before loading (``FrameRef.pose``,
as every built-in reader gives them) and hidden (a plugin reader without it: each frame judged
once loaded), ``--repeat`` times each in one run; prints CPU and wall seconds, the loading and
detection stages, and whether the two maps are the same.

    python benchmarks/bench_still.py [--mode replay|jobs|dask] [--model PATH] [--repeat 2]

replay: detections replayed after a first pass (loading and mapping only), one thread; jobs: the
model detecting, ``--jobs 2``; dask: the model detecting on two single-thread Dask workers in this
process (the readers registered here are theirs too).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import numpy as np  # noqa: E402

from ltc_cli import hookimpl, plugins  # noqa: E402
from ltc_cli.config import load_config  # noqa: E402
from ltc_cli.ingest.session import ingest  # noqa: E402
from ltc_cli.map.store import load_map  # noqa: E402
from real_stops import STOP_FRAMES, STOPS  # noqa: E402
from tests.replay import Replay, Stopped  # noqa: E402
from tests.shared_data import SHARED  # noqa: E402


class Hidden(Stopped):
    """The stopped recording with no pose known before loading."""

    def open(self, path, options):
        rec = super().open(path, options)
        return replace(rec, frames=[replace(ref, pose=None) for ref in rec.frames])


class BenchPlugin:
    @hookimpl
    def register_readers(self, register):
        register("stopped", Stopped(STOPS, STOP_FRAMES))
        register("stopped-hidden", Hidden(STOPS, STOP_FRAMES))

    @hookimpl
    def register_detectors(self, register):
        register("replay-yolo", Replay)


READERS = (("stopped", "poses known before loading"), ("stopped-hidden", "judged once loaded"))


def table(m: Path) -> np.ndarray:
    c = load_map(m).objects.columns()
    return np.concatenate([c["center"], c["size"], c["scores"]], axis=1)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--mode", choices=("replay", "jobs", "dask"), default="replay")
    ap.add_argument("--model", default=str(SHARED / "models" / "yolov8n-seg_fp32.onnx"))
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    path = SHARED / "data" / "tum-fr1-rpy"
    if not Path(args.model).is_file() or not path.is_dir():
        sys.exit(f"bench_still: {args.model} or {path} not found (needs ../shared)")
    plugins.register_plugin(BenchPlugin(), name="bench-still")
    det = "replay-yolo" if args.mode == "replay" else "onnx-yolo-seg"
    cfg = load_config(None, [f"detector.name={det}", f"detector.options.model={args.model}"])
    kw: dict = {"jobs": 2} if args.mode == "jobs" else {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        if args.mode == "replay":
            ingest([path], tmp / "warm.h5", cfg, reader="stopped")
        if args.mode == "dask":
            import distributed

            from ltc_cli.ingest.cluster import Cluster

            local = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=":0")
            kw["cluster"] = Cluster(distributed.Client(local), local)
        print(f"tum-fr1-rpy stopped {STOP_FRAMES} frames after frames {STOPS}; mode {args.mode}")
        try:
            for rep in range(args.repeat):
                maps = {}
                for reader, label in READERS:
                    m = tmp / f"{reader}-{rep}.h5"
                    c0, w0 = time.process_time(), time.perf_counter()
                    s = ingest([path], m, cfg, reader=reader, **kw)
                    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
                    print(f"  {label:27s} {cpu:5.1f} s CPU {wall:5.1f} s wall; {s.frames_done} mapped, "
                          f"{s.frames_still} still; loading {s.stage_seconds['load']:.1f} s, "
                          f"detection {s.stage_seconds['detect']:.1f} s", flush=True)
                    maps[reader] = table(m)
                print(f"  same map: {np.array_equal(maps['stopped'], maps['stopped-hidden'])}")
        finally:
            if "cluster" in kw:
                kw["cluster"].close()


if __name__ == "__main__":
    main()

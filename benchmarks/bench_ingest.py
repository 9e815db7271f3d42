"""Detection throughput and end-to-end ingest speed with a real model, sequential vs ``--jobs``.

Uses the ``onnx-yolo-seg`` detector with the int8 YOLOv8n-seg model at
../shared/models/yolov8n-seg_int8.onnx on the five real RGB-D frames of ../shared/data/dining-room
(both read in place, never copied: see their READMEs). A temporary ltc-recording/1 folder repeats the
five frames (symlinks to the same images, the same poses) under ``--repeat`` x 5 frame ids, so that
the figures are stable. Prints:

- detection alone: ms per frame and frames/s on one thread, and the aggregate frames/s of two
  threads detecting at once (what ``--jobs 2`` can get from a detector declaring ``thread_safe``);
- ingest end to end (load, detect, map, commit; a fresh map each time): frames/s with jobs 1, with
  jobs 2 (the detector is ``thread_safe``: two ``detect`` calls at once), and with jobs 2 for a
  detector that is not (one ``detect`` at a time), checking that every run makes the same map.

Each ingest figure is the fastest of ``--trials`` runs (the machine may be busy with other work).

    python benchmarks/bench_ingest.py [--repeat 8] [--trials 2] [--model PATH] [--data DIR]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from ltc_cli import plugins  # noqa: E402
from ltc_cli.config import defaults  # noqa: E402
from ltc_cli.ingest.session import ingest  # noqa: E402
from ltc_cli.recordings.open import open_recording  # noqa: E402
from ltc_cli.map.store import load_map  # noqa: E402

SHARED = ROOT.parent / "shared"
MODEL = SHARED / "models" / "yolov8n-seg_int8.onnx"
DATA = SHARED / "data" / "dining-room"
RECORDING_YAML = """\
format: ltc-recording/1
name: dining-room (slambook2 ch5/rgbd), each frame repeated
camera: {width: 640, height: 480, fx: 518.0, fy: 519.0, cx: 325.5, cy: 253.5}
depth: {scale: 1000.0, min: 0.3, max: 6.0}
up: estimate
"""


def make_recording(data: Path, dest: Path, repeat: int) -> int:
    """An ltc-recording/1 folder at dest: frame k*5+n (n = 1..5) -> colour/depth/pose of frame n."""
    (dest / "rgb").mkdir(parents=True)
    (dest / "depth").mkdir()
    (dest / "recording.yaml").write_text(RECORDING_YAML)
    poses = [ln.split() for ln in (data / "pose.txt").read_text().splitlines() if ln.strip()]
    lines = []
    for k in range(repeat):
        for n, pose in enumerate(poses, start=1):
            fid = f"{k:02d}{n:02d}"
            os.symlink(data / "color" / f"{n}.png", dest / "rgb" / f"{fid}.png")
            os.symlink(data / "depth" / f"{n}.pgm", dest / "depth" / f"{fid}.pgm")
            lines.append(" ".join([fid, *pose]))
    (dest / "poses.txt").write_text("\n".join(lines) + "\n")
    return len(lines)


def detection_throughput(rec_path: Path, model: Path, frames: int):
    rec = open_recording(rec_path)
    det = plugins.get("detectors", "onnx-yolo-seg").factory(rec, {"model": str(model)})
    loaded = [ref.load() for ref in rec.frames[:5]]
    for fr in loaded[:2]:  # warm-up
        det.detect(fr)
    times = []
    n_det = 0
    for i in range(frames):
        t0 = time.perf_counter()
        n_det += len(det.detect(loaded[i % 5]))
        times.append(time.perf_counter() - t0)
    one = statistics.median(times)

    # Two threads calling detect on the same session at once (onnxruntime's Run is thread-safe).
    per_thread = frames // 2
    def work():
        for i in range(per_thread):
            det.detect(loaded[i % 5])

    threads = [threading.Thread(target=work) for _ in range(2)]
    t0 = time.perf_counter()
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    two = (2 * per_thread) / (time.perf_counter() - t0)
    return one, n_det / frames, two


def state(path):
    smap = load_map(path)
    return ({k: v.copy() for k, v in smap.objects.columns().items()},
            [(e.session, e.frame, e.kind, e.object_id, e.other_id) for e in smap.events])


def same_map(a, b) -> bool:
    (ca, ea), (cb, eb) = state(a), state(b)
    return ea == eb and all(np.array_equal(ca[k], cb[k]) for k in ca)


def run_ingest(rec_path: Path, model: Path, map_path: Path, jobs: int):
    cfg = defaults()
    cfg["detector"] = {"name": "onnx-yolo-seg", "options": {"model": str(model)}}
    t0 = time.perf_counter()
    s = ingest([rec_path], map_path, cfg, jobs=jobs, checkpoint_every=50)
    wall = time.perf_counter() - t0
    return s, wall


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=8, help="times the 5 frames are repeated (default 8: 40 frames)")
    ap.add_argument("--trials", type=int, default=2, help="ingest runs per setting; the fastest is shown (default 2)")
    ap.add_argument("--model", type=Path, default=MODEL)
    ap.add_argument("--data", type=Path, default=DATA)
    args = ap.parse_args(argv)
    if not args.model.is_file():
        print(f"skipped: no model at {args.model} (see ../shared/models/README.md)")
        return 0
    if not (args.data / "pose.txt").is_file():
        print(f"skipped: no dining-room frames at {args.data}")
        return 0
    print(f"machine: {os.cpu_count()} CPUs; model {args.model.name}; onnxruntime intra-op threads 1 (the default)")
    with tempfile.TemporaryDirectory(prefix="ltc-bench-ingest-") as tmp:
        tmp = Path(tmp)
        rec = tmp / "dining-room"
        n = make_recording(args.data, rec, args.repeat)
        one, per_frame, two = detection_throughput(rec, args.model, n)
        print(f"detection, 1 thread : {1000 * one:6.1f} ms/frame  {1 / one:5.2f} frames/s  "
              f"({per_frame:.1f} instances/frame, 640x480 -> 320x320 input)")
        print(f"detection, 2 threads: {1000 / two:6.1f} ms/frame  {two:5.2f} frames/s  (aggregate, two detect calls at once)")

        from ltc_plugins.onnx.yolo_seg import YoloSegDetector

        results = {}
        for label, jobs, safe in (("jobs 1", 1, True), ("jobs 2, one detect at a time", 2, False), ("jobs 2", 2, True)):
            if not safe:
                YoloSegDetector.thread_safe = False
            try:
                best = None
                for trial in range(max(1, args.trials)):
                    m = tmp / f"{label.replace(' ', '_').replace(',', '')}-{trial}.h5"
                    s, wall = run_ingest(rec, args.model, m, jobs)
                    if best is not None and not same_map(best[0], m):
                        print(f"{label}: two runs made different maps")
                        return 1
                    if best is None or wall < best[2]:
                        best = (m, s, wall)
                m, s, wall = best
            finally:
                YoloSegDetector.thread_safe = True
            results[label] = (m, s, wall)
            st = s.stage_seconds
            mapping = sum(st[k] for k in ("modeling", "association", "integration", "maintenance", "merge"))
            print(f"ingest {label:<20}: {s.frames_done} frames in {wall:5.2f} s = {s.frames_done / wall:5.2f} frames/s "
                  f"({1000 * wall / s.frames_done:6.1f} ms/frame; per frame: load {1000 * st['load'] / s.frames_done:5.1f}, "
                  f"detect {1000 * st['detect'] / s.frames_done:6.1f}, map {1000 * mapping / s.frames_done:5.1f} ms); "
                  f"{s.objects} objects")
        base = results["jobs 1"]
        for label in ("jobs 2, one detect at a time", "jobs 2"):
            m, s, wall = results[label]
            ok = same_map(base[0], m)
            print(f"{label}: {base[2] / wall:4.2f}x the speed of jobs 1; map identical to jobs 1: {'yes' if ok else 'NO'}")
            if not ok:
                return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())

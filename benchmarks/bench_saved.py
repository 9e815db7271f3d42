"""Detect once, map many times (``detector.save_to``), and the session rows read alone, in one run.

1. tum-fr1-rpy with the fp32 YOLOv8n-seg model, one thread, each ingest a child process measured on
   its own (os.wait4), the three kinds alternating ``--repeats`` times: the model alone; the model
   writing its detections (``--set detector.save_to=DIR``); and the replay of that folder by the
   ``recorded`` detector (``--set detector.options.folder=DIR``). Prints CPU (user + system) and
   wall seconds, and whether each replay's map equals the model's (objects, ids, events, frame
   keys, class list). Needs ../shared.
2. The session rows of a 100,000-object map (tests/sample_maps.big_map): ``store.load_sessions``
   against ``load_map(events=False).sessions``, what an ingest read before it opens its recordings
   until the fifty-sixth round; CPU seconds in this process.

    python benchmarks/bench_saved.py [--model ../shared/models/yolov8n-seg_fp32.onnx] [--repeats 2]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_real import SHARED  # noqa: E402
from bench_scale import LTC, measure  # noqa: E402

from ltc_cli.map.store import load_map, load_sessions, save_map  # noqa: E402


def same_map(a: Path, b: Path) -> bool:
    ma, mb = load_map(a), load_map(b)
    ca, cb = ma.objects.columns(), mb.objects.columns()
    return (ma.classes == mb.classes and ca.keys() == cb.keys() and all(np.array_equal(ca[k], cb[k]) for k in ca)
            and np.array_equal(ma.objects.ids, mb.objects.ids) and ma.events == mb.events
            and ma.frame_keys == mb.frame_keys)


def replay_part(model: Path, repeats: int, tmp: Path) -> None:
    rec = SHARED / "data" / "tum-fr1-rpy"
    if not (rec.is_dir() and model.is_file()):
        print(f"skipped the replay: needs {rec} and {model}")
        return
    det = ["--detector", "onnx-yolo-seg", "--set", f"detector.options.model={model}", "--jobs", "1"]
    rows: dict = {"the model": [], "the model, saving": [], "replaying the saved folder": []}
    same = []
    for k in range(repeats):
        m_model, m_save, m_replay, saved = (tmp / f"{name}{k}" for name in ("model.h5", "save.h5", "replay.h5", "dets"))
        rows["the model"].append(measure([*LTC, "ingest", str(rec), "--map", str(m_model), *det]))
        rows["the model, saving"].append(measure([*LTC, "ingest", str(rec), "--map", str(m_save), *det,
                                                  "--set", f"detector.save_to={saved}"]))
        rows["replaying the saved folder"].append(measure([*LTC, "ingest", str(rec), "--map", str(m_replay),
                                                           "--set", f"detector.options.folder={saved}"]))
        same.append(same_map(m_model, m_replay))
    print(f"tum-fr1-rpy, {model.name}, one thread, {repeats} runs of each, alternating (CPU s = user + system)")
    for label, runs in rows.items():
        cpu = ", ".join(f"{c:.2f}" for c, _, _ in runs)
        wall = ", ".join(f"{w:.2f}" for _, w, _ in runs)
        print(f"  {label:<28} CPU {cpu} s; wall {wall} s")
    print(f"  each replay's map equals the model's (objects, ids, events, frame keys, classes): "
          f"{'yes' if all(same) else 'NO'} ({sum(same)} of {len(same)})")


def sessions_part(tmp: Path, repeats: int) -> None:
    from tests.sample_maps import big_map

    path = tmp / "big.h5"
    save_map(big_map(100_000), path)
    print("the session rows of a 100,000-object map, CPU s in this process")
    for _ in range(max(repeats, 3)):
        t0 = time.process_time()
        whole = load_map(path, events=False).sessions
        t1 = time.process_time()
        alone = load_sessions(path)
        t2 = time.process_time()
        print(f"  load_map(events=False).sessions {t1 - t0:.4f} s; load_sessions {t2 - t1:.4f} s; "
              f"the same rows: {'yes' if whole == alone else 'NO'}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", type=Path, default=SHARED / "models" / "yolov8n-seg_fp32.onnx")
    ap.add_argument("--repeats", type=int, default=2)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as t:
        replay_part(args.model.resolve(), args.repeats, Path(t))
        sessions_part(Path(t), args.repeats)


if __name__ == "__main__":
    main()

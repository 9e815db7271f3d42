"""A long TUM recording read and checked: tum-fr1-rpy's lists repeated to ``--frames`` frames (the
images linked, not copied; the trajectory shifted in time each repeat, so a repeat starts where the
first did), then:

1. ``ltc check`` on it, in a child process (CPU = user + system, wall, max RSS);
2. in this process: opening it with the TUM reader, and reading every frame's pose before loading
   (``FrameRef.pose``, what ``ltc check`` and an ingest's still-frame test ask of each frame).

Needs ../shared.

    python benchmarks/bench_check.py [--frames 100000] [--repeats 2]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_real import SHARED  # noqa: E402
from bench_scale import LTC, measure  # noqa: E402

from ltc_plugins.readers.tum import TumReader  # noqa: E402


def long_tum(source: Path, folder: Path, n_frames: int) -> None:
    """``source``'s lists repeated until they hold ``n_frames`` colour lines; images linked."""
    def rows(name):
        return [line.split() for line in (source / name).read_text().splitlines() if line.strip() and line[0] != "#"]

    rgb, depth, gt = rows("rgb.txt"), rows("depth.txt"), rows("groundtruth.txt")
    span = float(gt[-1][0]) - float(gt[0][0]) + 1.0
    folder.mkdir(parents=True)
    for sub in ("rgb", "depth"):
        (folder / sub).symlink_to(source / sub)
    repeats = -(-n_frames // len(rgb))
    with (folder / "rgb.txt").open("w") as f_rgb, (folder / "depth.txt").open("w") as f_depth, \
            (folder / "groundtruth.txt").open("w") as f_gt:
        for k in range(repeats):
            shift = k * span
            f_rgb.writelines(f"{float(t) + shift:.6f} {name}\n" for t, name in rgb[: n_frames - k * len(rgb)])
            f_depth.writelines(f"{float(t) + shift:.6f} {name}\n" for t, name in depth)
            f_gt.writelines(f"{float(r[0]) + shift:.4f} {' '.join(r[1:])}\n" for r in gt)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=100_000)
    ap.add_argument("--repeats", type=int, default=2)
    args = ap.parse_args()
    source = SHARED / "data" / "tum-fr1-rpy"
    if not source.is_dir():
        raise SystemExit(f"needs {source}")
    with tempfile.TemporaryDirectory() as tmp:
        rec = Path(tmp) / "long-tum"
        long_tum(source, rec, args.frames)
        print(f"tum-fr1-rpy's lists repeated to {args.frames} colour lines")
        for k in range(args.repeats):
            cpu, wall, rss = measure([*LTC, "check", str(rec)])
            print(f"  ltc check: {cpu:.2f} s CPU, {wall:.2f} s wall, {rss:.0f} MiB")
        for k in range(args.repeats):
            t0 = time.process_time()
            recording = TumReader().open(rec, {})
            t1 = time.process_time()
            for ref in recording.frames:
                ref.pose()
            t2 = time.process_time()
            print(f"  the TUM reader: open {t1 - t0:.2f} s CPU; every frame's pose {t2 - t1:.2f} s CPU "
                  f"({len(recording.frames)} frames, {1e6 * (t2 - t1) / len(recording.frames):.1f} us a frame)")


if __name__ == "__main__":
    main()

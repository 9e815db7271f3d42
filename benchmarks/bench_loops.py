"""A route driven many times: tum-fr1-rpy's lists repeated ``--loops`` times (the images linked, each
loop the same poses shifted in time; bench_check.long_tum), mapped with the fp32 model's detections
(detected once, replayed: ``detector.save_to``), two ways:

1. as one session over every loop;
2. one loop per session (``ltc ingest --frames 0:232``, ``232:464``, ...).

Prints each map's objects per class against the counted truth (bench_real.py), the objects that the
end of the one long session removed as unconfirmed though detected from two views or more, and
whether the loop-per-session map kept the first loop's ids. Needs ../shared. About 10 s a loop.

    python benchmarks/bench_loops.py [--loops 43] [--extra 0] [--model ../shared/models/yolov8n-seg_fp32.onnx]
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_check import long_tum  # noqa: E402
from bench_real import SHARED, verdict  # noqa: E402
from bench_scale import LTC  # noqa: E402

from ltc_cli.map.model import top_class  # noqa: E402
from ltc_cli.map.store import load_map  # noqa: E402


def ltc(*args) -> None:
    proc = subprocess.run([*LTC, *map(str, args)], capture_output=True, text=True, cwd=tempfile.gettempdir())
    if proc.returncode != 0:
        raise SystemExit(f"ltc {' '.join(map(str, args))} failed:\n{proc.stderr}")


def classes_of(m: Path) -> Counter:
    smap = load_map(m)
    top = top_class(smap.objects.scores)
    return Counter(smap.classes[top[r]] for r in smap.active_rows())


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--loops", type=int, default=43)
    ap.add_argument("--extra", type=int, default=0,
                    help="frames of one more loop after the last (the set-up is estimated on all the frames)")
    ap.add_argument("--model", type=Path, default=SHARED / "models" / "yolov8n-seg_fp32.onnx")
    args = ap.parse_args()
    source = SHARED / "data" / "tum-fr1-rpy"
    if not (source.is_dir() and args.model.is_file()):
        raise SystemExit(f"needs {source} and {args.model}")
    n = sum(1 for line in (source / "rgb.txt").read_text().splitlines() if line.strip() and line[0] != "#")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        saved = tmp / "saved"
        ltc("ingest", source, "--map", tmp / "once.h5", "--detector", "onnx-yolo-seg",
            "--set", f"detector.options.model={args.model}", "--set", "frames.still_move=null",
            "--set", f"detector.save_to={saved}")
        rec = tmp / "loops"
        long_tum(source, rec, n * args.loops + args.extra)
        # Each loop's frames replay the first loop's detections under their shifted keys.
        dets = tmp / "dets"
        dets.mkdir()
        os.symlink(saved / "classes.json", dets / "classes.json")
        first = [line.split()[0] for line in (source / "rgb.txt").read_text().splitlines()
                 if line.strip() and line[0] != "#"]
        for k, line in enumerate((rec / "rgb.txt").read_text().splitlines()):
            os.symlink(saved / f"{first[k % n]}.json", dets / f"{line.split()[0]}.json")
        replay = ["--set", f"detector.options.folder={dets}"]
        one, per = tmp / "one.h5", tmp / "per.h5"
        ltc("ingest", rec, "--map", one, *replay)
        for k in range(args.loops):
            ltc("ingest", rec, "--map", per, *replay, "--frames", f"{k * n}:{(k + 1) * n}")
            if k == 0:
                first_ids = set(load_map(per).objects.ids[load_map(per).active_rows()].tolist())
        print(f"tum-fr1-rpy driven {args.loops} times and {args.extra} frames ({n * args.loops + args.extra} frames), "
              f"{args.model.name} detections replayed")
        for name, m in ((f"one session of {args.loops} loops", one), (f"{args.loops} sessions, one loop each", per)):
            counts = classes_of(m)
            print(f"  {name}: {sum(counts.values())} objects ({verdict('tum-fr1-rpy', counts)}); "
                  + ", ".join(f"{c} {k}" for c, k in sorted(counts.items())))
        smap = load_map(one)
        t, top = smap.objects, top_class(smap.objects.scores)
        shares = [f"{smap.classes[top[r]]} {t.ids[r]} {t.n_det[r]}/{t.n_clear[r]}" for r in smap.active_rows()
                  if t.n_clear[r] > 0]
        print(f"    the long session's objects, detections / clear views: {'; '.join(shares)}")
        active = set(smap.active_rows().tolist())
        for r in range(t.n):
            # The desk called a dining table: while its box stands, every ray to a thing on the desk
            # enters it first and the thing has no clear view (docs/decisions.md, fifty-eighth round).
            if top[r] < len(smap.classes) and smap.classes[top[r]] == "dining table" and t.n_det[r] >= args.loops:
                lo, hi = t.center[r][2] - t.size[r][2] / 2, t.center[r][2] + t.size[r][2] / 2
                print(f"    dining table {t.ids[r]} ({'in the map' if r in active else 'removed'}): "
                      f"{t.size[r][0]:.2f} x {t.size[r][1]:.2f} m, z {lo:.2f} to {hi:.2f} m, "
                      f"{t.n_det[r]} detections in {t.n_clear[r]} clear views")
        for e in smap.events:
            views = re.search(r"detected from (\d+) distinct view", e.detail or "")
            r = e.object_id - 1
            # Removed at the session's end though detected twice a loop or more, from two views or more.
            if e.kind == "removed" and views and int(views.group(1)) >= 2 and t.n_det[r] >= 2 * args.loops:
                name = smap.classes[top[r]] if top[r] < len(smap.classes) else "other"
                where = f"({t.center[r][0]:.2f}, {t.center[r][1]:.2f})"
                print(f"    the long session removed {name} {t.ids[r]} at {where}: "
                      f"{t.n_det[r]} detections in {t.n_clear[r]} clear views "
                      f"({t.n_det[r] / max(t.n_clear[r], 1):.1%}), from {views.group(1)} views")
        smap = load_map(per)
        kept = first_ids & set(smap.objects.ids[smap.active_rows()].tolist())
        print(f"  one loop per session: the first loop's ids kept to the last: {len(kept)} of {len(first_ids)}")


if __name__ == "__main__":
    main()

"""Accuracy on simulated houses: each metric x policy, after lap 1 and after lap 2.

Simulates several two-lap houses (seeds other than the sample data's), ingests lap 1 then lap 2 into
one map with every combination of association metric (vertex / centroid) and maintenance policy
(non-detection / static), and prints the per-lap table like the paper's Tables 1-2, summed over the
houses. The houses use the simulator's realistic profile (pose drift, per-class and correlated
misses, systematic mislabels, phantoms, CNN-like masks, depth holes, people; docs/simulator.md)
unless --profile benign. Simulated houses are cached in benchmarks/.cache (delete it to rebuild).

    python benchmarks/bench_accuracy.py [--houses 4] [--scene small] [--profile realistic|benign]
        [--set key=value]... [--sim option=value]...
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numpy as np  # noqa: E402

from ltc_cli.config import load_config  # noqa: E402
from ltc_cli.tools.evaluate import evaluate_map  # noqa: E402
from ltc_cli.recordings.groundtruth import read_ground_truth  # noqa: E402
from ltc_cli.ingest.session import ingest  # noqa: E402
from ltc_cli.tools.simulate import simulate  # noqa: E402
from ltc_cli.map.store import load_map  # noqa: E402

CACHE = Path(__file__).resolve().parent / ".cache"
COMBOS = [("vertex", "non-detection"), ("vertex", "static"), ("centroid", "non-detection"), ("centroid", "static")]


def house(scene: str, seed: int, sim_sets=(), profile: str = "realistic") -> Path:
    tag = "-".join([scene, str(seed), profile] + [s.replace("=", "_") for s in sim_sets])
    out = CACHE / tag
    if not (out / "lap2" / "ground_truth.json").is_file():
        import shutil

        shutil.rmtree(out, ignore_errors=True)
        opts = {}
        for s in sim_sets:
            k, v = s.split("=", 1)
            opts[k] = float(v) if "." in v else int(v)
        simulate(out, scene=scene, laps=2, seed=seed, profile=profile, **opts)
    return out


def add(total: dict, res: dict) -> None:
    for k in ("tp", "fp", "fn", "duplicates", "ghosts", "num_map"):
        total[k] = total.get(k, 0) + res[k]
    for k in ("xy_iou", "viou", "position_error"):
        total.setdefault(k, []).extend(m[k] for m in res["matches"])
    seen = res.get("_seen")
    total["fn_seen"] = total.get("fn_seen", 0) + seen


def row(name: str, t: dict) -> str:
    tp, fp, fn, fns = t["tp"], t["fp"], t["fn"], t["fn_seen"]
    p = tp / (tp + fp) if tp + fp else 0.0
    r = tp / (tp + fn) if tp + fn else 0.0
    rs = tp / (tp + fns) if tp + fns else 0.0
    f1 = 2 * p * r / (p + r) if p + r else 0.0
    n = max(t["num_map"], 1)
    return (f"{name:<28}{tp:>5}{fp:>5}{fn:>5} {p:>6.3f} {r:>6.3f} {rs:>7.3f} {f1:>6.3f} "
            f"{np.mean(t['xy_iou']):>7.3f} {np.mean(t['viou']):>6.3f} {np.mean(t['position_error']):>7.3f} "
            f"{t['duplicates'] / n:>6.1%} {t['ghosts'] / n:>6.1%}")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--houses", type=int, default=4)
    ap.add_argument("--scene", default="small")
    ap.add_argument("--first-seed", type=int, default=101)
    ap.add_argument("--profile", choices=["realistic", "benign"], default="realistic",
                    help="the simulator's profile (default realistic)")
    ap.add_argument("--config", help="ltc config file (e.g. docs/paper.yaml for the paper's behaviour)")
    ap.add_argument("--set", dest="sets", action="append", default=[], help="ltc config override")
    ap.add_argument("--sim", dest="sim", action="append", default=[], help="simulator option override")
    ap.add_argument("--combos", default="all", help="all, or e.g. vertex/non-detection")
    ap.add_argument("--calibrate", action="store_true",
                    help="measure v_Other with ltc calibrate on each house's lap 1 and ingest with it")
    args = ap.parse_args()
    combos = COMBOS if args.combos == "all" else [tuple(c.split("/")) for c in args.combos.split(",")]
    t0 = time.time()
    houses = [house(args.scene, args.first_seed + i, args.sim, args.profile) for i in range(args.houses)]
    print(f"{args.houses} simulated '{args.scene}' houses ({args.profile} profile, "
          f"seeds {args.first_seed}..{args.first_seed + args.houses - 1}), "
          f"2 laps each; prepared in {time.time() - t0:.0f} s; config: {args.config or 'defaults'}; "
          f"v_Other: {'calibrated per house on lap 1' if args.calibrate else 'from the config'}; "
          f"overrides: {args.sets or 'none'}")
    head = (f"{'':<28}{'TP':>5}{'FP':>5}{'FN':>5} {'prec':>6} {'recall':>6} {'recall*':>7} {'F1':>6} "
            f"{'XY IoU':>7} {'VIoU':>6} {'poserr':>7} {'dup':>6} {'ghost':>6}")
    print(head)
    for metric, policy in combos:
        totals = [{}, {}]
        secs = 0.0
        frames = 0
        for h in houses:
            cal = None
            if args.calibrate:  # as `ltc calibrate lap1` then `ltc ingest --calibration`
                from ltc_cli.tools.calibrate import calibrate

                cal = calibrate(h / "lap1", "recorded", {}).to_document()
            with tempfile.TemporaryDirectory() as tmp:
                m = Path(tmp) / "map.h5"
                for lap in (1, 2):
                    cfg = load_config(args.config, [f"association.metric={metric}", f"maintenance.policy={policy}", *args.sets])
                    s = ingest([h / f"lap{lap}"], m, cfg, calibration=cal)
                    secs += s.seconds
                    frames += s.frames_done
                    gt = read_ground_truth(h / f"lap{lap}")
                    prev = read_ground_truth(h / "lap1") if lap == 2 else None
                    res = evaluate_map(load_map(m), gt, prev)
                    # FN among the objects the robot saw in this lap or before (the map covers both).
                    seen_ids = {o["id"] for o in gt["objects"] if o.get("seen_pixels", 1) > 0}
                    if prev is not None:
                        seen_ids |= {o["id"] for o in prev["objects"] if o.get("seen_pixels", 1) > 0}
                    res["_seen"] = sum(1 for i in res["fn_ids"] if i in seen_ids)
                    add(totals[lap - 1], res)
        for lap in (1, 2):
            print(row(f"{metric}/{policy} lap {lap}", totals[lap - 1]))
        print(f"{'':<28}ingest {1000 * secs / max(frames, 1):.1f} ms/frame (incl. reading)")
    print("recall* = over the ground-truth objects the robot saw; dup / ghost as % of map objects")


if __name__ == "__main__":
    main()

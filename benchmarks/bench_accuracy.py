"""Accuracy on simulated houses: each metric x policy, after every lap.

Simulates several houses of N laps (default 2; seeds other than the sample data's), ingests lap 1,
lap 2, ... into one map with every combination of association metric (vertex / centroid) and
maintenance policy (non-detection / static), and prints the per-lap table like the paper's Tables
1-2, summed over the houses; then, per lap, the figures that cannot be flattered (docs/evaluation.md):
precision / recall / F1 with a TP needing XY IoU > 0.25 (and > 0.5, compact), duplicates, ghosts of
any earlier lap, present objects deleted by maintenance and ids kept since the lap before. The houses
use the simulator's realistic profile (pose drift, per-class and correlated misses, systematic
mislabels, phantoms, CNN-like masks, depth holes, people; docs/simulator.md) unless --profile benign.
Simulated houses are cached in benchmarks/.cache (delete it to rebuild).

    python benchmarks/bench_accuracy.py [--houses 4] [--scene small] [--laps 2] [--profile realistic|benign]
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
from ltc_cli.tools.evaluate import evaluate_map, ids_kept  # noqa: E402
from ltc_cli.recordings.groundtruth import read_ground_truth  # noqa: E402
from ltc_cli.ingest.session import ingest  # noqa: E402
from ltc_cli.tools.simulate import simulate  # noqa: E402
from ltc_cli.map.store import load_map  # noqa: E402

CACHE = Path(__file__).resolve().parent / ".cache"
COMBOS = [("vertex", "non-detection"), ("vertex", "static"), ("centroid", "non-detection"), ("centroid", "static")]


def house(scene: str, seed: int, sim_sets=(), laps: int = 2, profile: str = "realistic") -> Path:
    tag = "-".join([scene, str(seed), profile] + [s.replace("=", "_") for s in sim_sets]
                   + ([] if laps == 2 else [f"laps{laps}"]))
    out = CACHE / tag
    if not (out / f"lap{laps}" / "ground_truth.json").is_file():
        import shutil

        shutil.rmtree(out, ignore_errors=True)
        opts = {}
        for s in sim_sets:
            k, v = s.split("=", 1)
            opts[k] = float(v) if "." in v else int(v)
        simulate(out, scene=scene, laps=laps, seed=seed, profile=profile, **opts)
    return out


def add(total: dict, res: dict) -> None:
    for k in ("tp", "fp", "fn", "duplicates", "ghosts", "num_map"):
        total[k] = total.get(k, 0) + res[k]
    for k in ("xy_iou", "viou", "position_error"):
        total.setdefault(k, []).extend(m[k] for m in res["matches"])
    total["fn_seen"] = total.get("fn_seen", 0) + res["_seen"]["0"]


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


def seen_fn_counts(res: dict, seen_ids: set) -> dict:
    """FN among the objects the robot saw in this lap or before (the map covers all of them), at any
    overlap ("0") and at each XY IoU level."""
    levels = {"0": res, **res["at_iou"]}
    return {t: sum(1 for i in r["fn_ids"] if i in seen_ids) for t, r in levels.items()}


def add_strict(total: dict, res: dict, kept: dict | None) -> None:
    """Sum the IoU-level counts, deletions of present objects and ids kept of one house's lap."""
    for t, r in res["at_iou"].items():
        lv = total.setdefault(t, {})
        for k in ("tp", "fp", "fn"):
            lv[k] = lv.get(k, 0) + r[k]
        lv["fn_seen"] = lv.get("fn_seen", 0) + res["_seen"][t]
    d = res["deleted_while_present"]
    total["deleted"] = total.get("deleted", 0) + d["count"]
    total["present"] = total.get("present", 0) + d["present"]
    if kept is not None:
        total["kept"] = total.get("kept", 0) + kept["kept"]
        total["tracked"] = total.get("tracked", 0) + kept["tracked"]


def percent(num, den) -> str:
    return "n/a" if not den else f"{num / den:.1%}"


def ratio(num, den) -> str:
    return "n/a" if not den else f"{num / den:.3f}"


STRICT_HEAD = (f"{'XY IoU > 0.25':<28}{'TP':>5}{'FP':>5}{'FN':>5} {'prec':>6} {'recall':>6} {'recall*':>7} {'F1':>6}"
               f"  {'P / R / F1 at > 0.5':<20}{'dup':>6} {'ghost':>6} {'deleted':>8} {'ids kept':>9}")


def strict_row(name: str, t: dict, s: dict) -> str:
    """One lap's row: at XY IoU > 0.25, > 0.5 (compact), dup, ghosts (any earlier lap), present
    objects deleted by maintenance, ids kept since the lap before (n/a on lap 1)."""
    a, b = s["0.25"], s["0.5"]
    n = t["num_map"]
    half = "/".join(ratio(x, y) for x, y in ((b["tp"], b["tp"] + b["fp"]), (b["tp"], b["tp"] + b["fn"]),
                                          (2 * b["tp"], 2 * b["tp"] + b["fp"] + b["fn"])))
    return (f"{name:<28}{a['tp']:>5}{a['fp']:>5}{a['fn']:>5} {ratio(a['tp'], a['tp'] + a['fp']):>6} "
            f"{ratio(a['tp'], a['tp'] + a['fn']):>6} {ratio(a['tp'], a['tp'] + a['fn_seen']):>7} "
            f"{ratio(2 * a['tp'], 2 * a['tp'] + a['fp'] + a['fn']):>6}  {half:<20}{percent(t['duplicates'], n):>6} "
            f"{percent(t['ghosts'], n):>6} {percent(s['deleted'], s['present']):>8} {percent(s.get('kept', 0), s.get('tracked', 0)):>9}")


def map_house(h: Path, metric: str, policy: str, laps: int, args, cal) -> list:
    """Ingest a house's laps one after the other into one map; after each lap evaluate the map
    against that lap (ghosts of every earlier lap). Returns [(result, kept | None, seconds, frames)]."""
    out = []
    earlier, seen_ids, before = [], set(), None
    with tempfile.TemporaryDirectory() as tmp:
        m = Path(tmp) / "map.h5"
        for lap in range(1, laps + 1):
            cfg = load_config(args.config, [f"association.metric={metric}", f"maintenance.policy={policy}", *args.sets])
            s = ingest([h / f"lap{lap}"], m, cfg, calibration=cal)
            gt = read_ground_truth(h / f"lap{lap}")
            res = evaluate_map(load_map(m), gt, earlier)
            seen_ids |= {o["id"] for o in gt["objects"] if o.get("seen_pixels", 1) > 0}
            res["_seen"] = seen_fn_counts(res, seen_ids)
            out.append((res, None if before is None else ids_kept(before, res), s.seconds, s.frames_done))
            earlier.append(gt)
            before = res
    return out


def house_arguments() -> argparse.ArgumentParser:
    """The options that say which houses and which config (shared with bench_breakdown.py)."""
    ap = argparse.ArgumentParser()
    ap.add_argument("--houses", type=int, default=4)
    ap.add_argument("--scene", default="small")
    ap.add_argument("--first-seed", type=int, default=101)
    ap.add_argument("--laps", type=int, default=2, help="laps per simulated house (ingested one after the other)")
    ap.add_argument("--profile", choices=["realistic", "benign"], default="realistic",
                    help="the simulator's profile (default realistic)")
    ap.add_argument("--config", help="ltc config file (e.g. docs/paper.yaml for the paper's behaviour)")
    ap.add_argument("--set", dest="sets", action="append", default=[], help="ltc config override")
    return ap


def main():
    ap = house_arguments()
    ap.add_argument("--sim", dest="sim", action="append", default=[], help="simulator option override")
    ap.add_argument("--combos", default="all", help="all, or e.g. vertex/non-detection")
    ap.add_argument("--calibrate", action="store_true",
                    help="measure v_Other with ltc calibrate on each house's lap 1 and ingest with it")
    args = ap.parse_args()
    combos = COMBOS if args.combos == "all" else [tuple(c.split("/")) for c in args.combos.split(",")]
    t0 = time.time()
    houses = [house(args.scene, args.first_seed + i, args.sim, args.laps, args.profile) for i in range(args.houses)]
    print(f"{args.houses} simulated '{args.scene}' houses ({args.profile} profile, "
          f"seeds {args.first_seed}..{args.first_seed + args.houses - 1}), "
          f"{args.laps} laps each; prepared in {time.time() - t0:.0f} s; config: {args.config or 'defaults'}; "
          f"v_Other: {'calibrated per house on lap 1' if args.calibrate else 'from the config'}; "
          f"overrides: {args.sets or 'none'}")
    head = (f"{'':<28}{'TP':>5}{'FP':>5}{'FN':>5} {'prec':>6} {'recall':>6} {'recall*':>7} {'F1':>6} "
            f"{'XY IoU':>7} {'VIoU':>6} {'poserr':>7} {'dup':>6} {'ghost':>6}")
    print(head)
    strict_rows = []
    for metric, policy in combos:
        totals = [{} for _ in range(args.laps)]
        strict = [{} for _ in range(args.laps)]
        secs = 0.0
        frames = 0
        for h in houses:
            cal = None
            if args.calibrate:  # as `ltc calibrate lap1` then `ltc ingest --calibration`
                from ltc_cli.tools.calibrate import calibrate

                cal = calibrate(h / "lap1", "recorded", {}).to_document()
            for lap, (res, kept, sec, nframes) in enumerate(map_house(h, metric, policy, args.laps, args, cal)):
                secs += sec
                frames += nframes
                add(totals[lap], res)
                add_strict(strict[lap], res, kept)
        for lap in range(args.laps):
            print(row(f"{metric}/{policy} lap {lap + 1}", totals[lap]))
            strict_rows.append(strict_row(f"{metric}/{policy} lap {lap + 1}", totals[lap], strict[lap]))
        print(f"{'':<28}ingest {1000 * secs / max(frames, 1):.1f} ms/frame (incl. reading)")
    print("recall* = over the ground-truth objects the robot saw; dup / ghost as % of map objects")
    print()
    print(STRICT_HEAD)
    print("\n".join(strict_rows))
    print("a TP needs footprint (XY) IoU > 0.25 (P / R / F1 at > 0.5 after the columns); ghost: where an object "
          "stood in any earlier lap; deleted: present objects on which maintenance removed a map object; ids "
          "kept: unchanged objects (centre within 0.1 m) matched to the same map id as after the lap before")


if __name__ == "__main__":
    main()

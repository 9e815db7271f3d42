"""Is a change better, house by house? Two configs on the same simulated houses, and the differences
of their lap-2 counts with 95 % bootstrap intervals over the houses.

Four houses a set move by a few objects between any two configs, and a change that gains on one
set and loses on another is read as noise, or not, by eye. This benchmark maps every house of the
development and held-out sets (small and medium, seeds 101-104, 201-204, 301-304, 401-404) and of
a fresh set that no rule was tuned on (501-508), once with the base config and once with the
candidate, and prints, for each count, the total of both and of the differences, with the 95 %
interval of that total when the houses are drawn again with replacement (a paired bootstrap: a
house's two maps are compared with each other, so the spread between houses does not hide the
change). An interval that excludes 0 is a difference these houses show, not their noise.

    python benchmarks/bench_paired.py --set association.adjoin_except=[] [--base-set k=v]... [--jobs 2]

Counts at the last lap: matched objects, false positives and misses at any overlap, matched at XY
IoU > 0.25, ghosts (a map object where an object stood in an earlier lap), duplicates, ids lost
(objects unchanged since the lap before whose map id changed) and present objects deleted.
"""

from __future__ import annotations

import argparse
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from types import SimpleNamespace

os.environ.setdefault("OMP_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402

import bench_accuracy as acc  # noqa: E402

#: (scene, first seed, houses): the six sets of bench_issue9.py and the third held-out set, and the
#: fresh set 501-508 (eight houses each, first used in issue 9's forty-second round).
SETS = [(scene, seed, 4) for seed in (101, 201, 301, 401) for scene in ("small", "medium")] \
    + [("small", 501, 8), ("medium", 501, 8)]
COUNTS = ("matched", "false pos.", "missed", "matched > 0.25", "ghosts", "duplicates", "ids lost", "deleted")


def house_counts(res: dict, kept: dict | None) -> np.ndarray:
    """(8,) the :data:`COUNTS` of one house's last lap from its evaluation and its ids kept."""
    lost = 0 if kept is None else kept["tracked"] - kept["kept"]
    return np.array([res["tp"], res["fp"], res["fn"], res["at_iou"]["0.25"]["tp"], res["ghosts"],
                     res["duplicates"], lost, res["deleted_while_present"]["count"]], dtype=np.int64)


def paired_bootstrap(diffs: np.ndarray, draws: int = 2000, seed: int = 0, level: float = 0.95) -> np.ndarray:
    """(2, K) the lower and upper percentile bounds of the total of each of K per-house differences
    (diffs (H, K)) when the H houses are drawn again with replacement ``draws`` times."""
    diffs = np.asarray(diffs, dtype=float)
    rng = np.random.default_rng(seed)
    picks = rng.integers(len(diffs), size=(draws, len(diffs)))
    totals = diffs[picks].sum(axis=1)  # (draws, K)
    tail = 100.0 * (1.0 - level) / 2.0
    return np.percentile(totals, [tail, 100.0 - tail], axis=0)


def f1(counts: np.ndarray) -> float:
    tp, fp, fn = (float(x) for x in counts[:3])
    return 2 * tp / (2 * tp + fp + fn) if tp else 0.0


def map_one(job) -> tuple[str, np.ndarray, np.ndarray]:
    """(house, base counts (8,), candidate counts (8,)) of one house."""
    scene, seed, laps, config, base_sets, sets = job
    h = acc.house(scene, seed, (), laps)
    out = []
    for s in (base_sets, sets):
        res, kept, _, _ = acc.map_house(h, "vertex", "non-detection", laps,
                                        SimpleNamespace(config=config, sets=list(s)), None)[-1]
        out.append(house_counts(res, kept))
    return h.name, out[0], out[1]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--set", dest="sets", action="append", default=[], help="the candidate's config override")
    ap.add_argument("--base-set", dest="base_sets", action="append", default=[], help="the base's config override")
    ap.add_argument("--config", help="ltc config file under both (default: the defaults)")
    ap.add_argument("--laps", type=int, default=2)
    ap.add_argument("--jobs", type=int, default=2, help="houses mapped at once (default 2)")
    ap.add_argument("--draws", type=int, default=2000, help="bootstrap draws (default 2000)")
    args = ap.parse_args(argv)
    if not args.sets and not args.base_sets:
        ap.error("give the candidate (--set) or the base (--base-set) an override")
    jobs = [(scene, first + i, args.laps, args.config, args.base_sets, args.sets)
            for scene, first, n in SETS for i in range(n)]
    with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        rows = list(pool.map(map_one, jobs))
    names = [r[0] for r in rows]
    base, cand = np.array([r[1] for r in rows]), np.array([r[2] for r in rows])
    diffs = cand - base
    print(f"{len(rows)} realistic houses, lap {args.laps}; base {args.base_sets or 'defaults'}, "
          f"candidate {args.sets or 'defaults'}")
    print("houses that differ (candidate - base): " + ", ".join(COUNTS))
    for name, d in zip(names, diffs):
        if d.any():
            print(f"  {name:<24}" + "".join(f"{int(x):>+4d}" for x in d))
    lo, hi = paired_bootstrap(diffs, args.draws)
    print(f"{'count':<16}{'base':>6}{'cand.':>7}{'diff':>6}  95 % interval (houses drawn again)")
    for k, name in enumerate(COUNTS):
        print(f"{name:<16}{base[:, k].sum():>6}{cand[:, k].sum():>7}{diffs[:, k].sum():>+6d}  "
              f"[{lo[k]:+.0f}, {hi[k]:+.0f}]")
    better = sum(f1(c) > f1(b) + 1e-12 for b, c in zip(base, cand))
    worse = sum(f1(c) < f1(b) - 1e-12 for b, c in zip(base, cand))
    print(f"F1 at any overlap per house: {better} better, {worse} worse, {len(rows) - better - worse} the same")
    tot_b, tot_c = base.sum(axis=0), cand.sum(axis=0)
    for label, t in (("base", tot_b), ("candidate", tot_c)):
        tp, fp, fn, tp25 = (int(x) for x in t[:4])
        n_map, n_gt = tp + fp, tp + fn
        print(f"{label:<10} P / R {tp / n_map:.3f} / {tp / n_gt:.3f}  (IoU > 0.25: {tp25 / n_map:.3f} / {tp25 / n_gt:.3f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Every simulated figure of issue 9 in one run, as the tables of docs/decisions.md: the realistic
houses the rules were developed on (seeds 101-104) and the held-out ones (201-204, 301-304 first
run in the twenty-fourth round, 401-404 in the thirty-eighth, and twice as many fresh houses,
501-508, in the forty-second), small and medium, after lap 2; the static policy and the paper's
config (docs/paper.yaml) on the development houses; the benign profile on the small ones; and with
``--five-laps`` every lap of five.

Each set is bench_breakdown.py's run (vertex metric, non-detection policy, benchmarks/.cache's
houses) in a child process, ``--jobs`` at a time; the figures are the same as its rows.

    python benchmarks/bench_issue9.py [--houses 4] [--jobs 2] [--five-laps] [--set k=v]...
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

import bench_accuracy as acc  # noqa: E402
import bench_breakdown as bd  # noqa: E402

PAPER = Path(__file__).resolve().parent.parent / "docs" / "paper.yaml"


def sets(five_laps: bool) -> list[tuple]:
    """(label, scene, first seed, laps, profile, config, extra overrides, houses per --houses) of
    each run."""
    out = [
        ("small", "small", 101, 2, "realistic", None, ()),
        ("medium", "medium", 101, 2, "realistic", None, ()),
        ("held-out small", "small", 201, 2, "realistic", None, ()),
        ("held-out medium", "medium", 201, 2, "realistic", None, ()),
        # First run in the twenty-fourth round, after every rule so far: a check on them.
        ("second held-out small", "small", 301, 2, "realistic", None, ()),
        ("second held-out medium", "medium", 301, 2, "realistic", None, ()),
        ("third held-out small", "small", 401, 2, "realistic", None, ()),
        ("third held-out medium", "medium", 401, 2, "realistic", None, ()),
        ("fresh small", "small", 501, 2, "realistic", None, (), 2),
        ("fresh medium", "medium", 501, 2, "realistic", None, (), 2),
        ("small, static policy", "small", 101, 2, "realistic", None, ("maintenance.policy=static",)),
        ("medium, static policy", "medium", 101, 2, "realistic", None, ("maintenance.policy=static",)),
        ("small, docs/paper.yaml", "small", 101, 2, "realistic", str(PAPER), ()),
        ("medium, docs/paper.yaml", "medium", 101, 2, "realistic", str(PAPER), ()),
        ("benign small", "small", 101, 2, "benign", None, ()),
    ]
    if five_laps:
        out += [("small, five laps", "small", 101, 5, "realistic", None, ()),
                ("medium, five laps", "medium", 101, 5, "realistic", None, ())]
    return out


def run_set(spec: tuple, houses: int, overrides: tuple) -> list[tuple[dict, dict]]:
    """[(any-overlap totals, IoU-level totals)] per lap of one set, summed over its houses."""
    _, scene, seed, laps, profile, config, extra = spec[:7]
    args = SimpleNamespace(keep=None, config=config, sets=[*extra, *overrides])
    totals = [({}, {}) for _ in range(laps)]
    for i in range(set_houses(spec, houses)):
        h = acc.house(scene, seed + i, (), laps, profile)
        for lap, (res, kept, *_) in enumerate(bd.run_house(h, laps, args)):
            acc.add(totals[lap][0], res)
            acc.add_strict(totals[lap][1], res, kept)
    return totals


def set_houses(spec: tuple, houses: int) -> int:
    """How many houses a set maps: --houses, times the spec's factor when it has one."""
    return houses * (spec[7] if len(spec) > 7 else 1)


def table_row(label: str, t: dict, s: dict) -> str:
    """| label | P / R (IoU > 0.25) | dup | ghosts | deleted | ids kept | of one lap."""
    a, n = s["0.25"], t["num_map"]
    any_overlap = f"{acc.ratio(t['tp'], t['tp'] + t['fp'])} / {acc.ratio(t['tp'], t['tp'] + t['fn'])}"
    strict = f"{acc.ratio(a['tp'], a['tp'] + a['fp'])} / {acc.ratio(a['tp'], a['tp'] + a['fn'])}"
    return (f"| {label} | {any_overlap} ({strict}) | {acc.percent(t['duplicates'], n)} | {acc.percent(t['ghosts'], n)} | "
            f"{acc.percent(s['deleted'], s['present'])} | {acc.percent(s.get('kept', 0), s.get('tracked', 0))} |")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--houses", type=int, default=4, help="houses per set (default 4; twice as many in the fresh sets)")
    ap.add_argument("--jobs", type=int, default=2, help="sets run at once (default 2)")
    ap.add_argument("--five-laps", action="store_true", help="also every lap of five (small, medium)")
    ap.add_argument("--set", dest="sets", action="append", default=[], help="ltc config override, for every set")
    args = ap.parse_args()
    specs = sets(args.five_laps)
    with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        results = list(pool.map(run_set, specs, [args.houses] * len(specs), [tuple(args.sets)] * len(specs)))
    print(f"{args.houses} houses per set ({2 * args.houses} in the fresh ones); overrides: {args.sets or 'none'}; P / R at any overlap, "
          "at XY IoU > 0.25 in brackets; duplicates, ghosts, present objects deleted, ids kept")
    print()
    print("| set, lap 2 | P / R | dup | ghosts | deleted | ids kept |")
    print("| --- | --- | --- | --- | --- | --- |")
    for spec, totals in zip(specs, results):
        if spec[3] == 2:
            print(table_row(f"{spec[0]} {spec[2]}-{spec[2] + set_houses(spec, args.houses) - 1}", *totals[1]))
    for spec, totals in zip(specs, results):
        if spec[3] > 2:
            print()
            print(f"| {spec[0]} | P / R | dup | ghosts | deleted | ids kept |")
            print("| --- | --- | --- | --- | --- | --- |")
            for lap, (t, s) in enumerate(totals):
                print(table_row(f"lap {lap + 1}", t, s))
    return 0


if __name__ == "__main__":
    sys.exit(main())

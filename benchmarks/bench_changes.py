"""How right ``ltc changes`` is on simulated two-lap houses: precision and recall of the change
report against the simulator's list of moved, removed and added objects, by change and by place
(ltc_cli/tools/evaluate_changes.py), summed over the houses, for a few move radii.

    python benchmarks/bench_changes.py [--houses 4] [--scene small] [--radius 1 2 4 8]
    python benchmarks/bench_changes.py --scale 20000   # CPU time of map_changes on a made-up map

With ``--scale N`` it only times ``map_changes`` on a made-up two-session map: N small objects removed
as unconfirmed in session 0 (a long-lived map's glimpses) and N / 4 added in session 1, at random in
a 100 m square, a third of them of each of three classes.

Houses are simulated with seeds 1.. (not the sample data's) and cached in benchmarks/.cache, shared
with bench_accuracy.py.
"""

from __future__ import annotations

import argparse
import copy
import os
import sys
import tempfile
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.bench_accuracy import house  # noqa: E402
from ltc_cli.config import load_config  # noqa: E402
from ltc_cli.ingest.session import ingest  # noqa: E402
from ltc_cli.map.changes import map_changes  # noqa: E402
from ltc_cli.map.store import load_map  # noqa: E402
from ltc_cli.recordings.groundtruth import read_ground_truth  # noqa: E402
from ltc_cli.tools.evaluate_changes import evaluate_changes  # noqa: E402


def scale(n: int) -> None:
    import time

    import numpy as np

    from ltc_cli.map.model import ACTIVE, REMOVED, Event, SemanticMap

    m = SemanticMap.new(["chair", "cup", "book"])
    m.sessions = [{}, {}]
    rng = np.random.default_rng(0)
    for k in range(n + n // 4):
        session, status = (0, REMOVED) if k < n else (1, ACTIVE)
        scores = np.zeros(4)
        scores[k % 3], scores[3] = 0.9, 0.1
        row = m.objects.append(center=[*rng.uniform(0, 100, 2), 0.8], yaw=0.0, size=[0.1, 0.1, 0.1], scores=scores,
                               status=status, first_session=session, last_session=session, n_det=1)
        m.events.append(Event(session, 1, "k", "created", row + 1))
        if status == REMOVED:
            m.events.append(Event(0, -1, "k", "removed", row + 1, 0, "unconfirmed: 1 detection"))
    best = None
    for _ in range(3):
        c0 = time.process_time()
        rep = map_changes(m, since=0)
        best = min(best or 1e9, time.process_time() - c0)
    print(f"map_changes on {n} glimpses and {n // 4} additions: {best:.3f} s CPU (fastest of 3); "
          f"{rep.count('added')} added, {rep.confirmed} confirmed")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scale", type=int, help="only time map_changes on a made-up map of this many glimpses")
    ap.add_argument("--houses", type=int, default=4)
    ap.add_argument("--scene", default="small")
    ap.add_argument("--radius", type=float, nargs="+", default=[1.0, 2.0, 4.0, 8.0])
    args = ap.parse_args()
    if args.scale:
        return scale(args.scale)
    # Each map judged twice: as ltc changes does (an addition where lap 1 never looked is first seen,
    # not added) and as before the sessions kept where they looked (every addition reported).
    variants = ("where lap 1 looked kept", "every addition reported")
    totals = {(v, r): {"by_change": [0, 0, 0], "by_place": [0, 0, 0]} for v in variants for r in args.radius}
    for seed in range(1, args.houses + 1):
        root = house(args.scene, seed)
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "m.h5"
            for lap in ("lap1", "lap2"):
                ingest([root / lap], path, load_config(None, []))
            smap = load_map(path)
        blind = copy.deepcopy(smap)
        for row in blind.sessions:
            row["coverage"] = ""
        before, after = read_ground_truth(root / "lap1"), read_ground_truth(root / "lap2")
        for v, m in zip(variants, (smap, blind)):
            for r in args.radius:
                rep = map_changes(m, move_radius=r)
                res = evaluate_changes(rep, before, after)
                for k in ("by_change", "by_place"):
                    for i, f in enumerate(("right", "reported", "true")):
                        totals[v, r][k][i] += res[k][f]
            if m is smap:
                print(f"house {args.scene} seed {seed}: {res['truth']} true changes, {res['reported']} reported "
                      f"(radius {r:g} m), {rep.first_seen} additions first seen where lap 1 never looked")
    for v in variants:
        print(f"{v}:")
        print(f"{'radius':>6}  {'by change: P':>12} {'R':>6}  {'by place: P':>11} {'R':>6}")
        for r in args.radius:
            (cr, crep, ctrue), (pr, prep, ptrue) = totals[v, r]["by_change"], totals[v, r]["by_place"]
            print(f"{r:>6g}  {cr / max(crep, 1):>12.2f} {cr / max(ctrue, 1):>6.2f}  {pr / max(prep, 1):>11.2f} "
                  f"{pr / max(ptrue, 1):>6.2f}   ({cr}/{crep}, {cr}/{ctrue}; {pr}/{prep}, {pr}/{ptrue})")


if __name__ == "__main__":
    main()

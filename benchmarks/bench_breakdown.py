"""Why the map is wrong on simulated houses: the errors of each lap by cause (ltc_cli/tools/breakdown.py).

Uses bench_accuracy's houses (benchmarks/.cache, realistic profile unless --profile benign) and
ingests them with the vertex metric and the non-detection policy (or --set / --config), printing
bench_accuracy's rows (any overlap; XY IoU > 0.25 with dup, ghosts, deleted, ids kept) and then,
per lap, every false positive, missed seen object and lost id by its cause (--list: one by one), and
what fails in each loose match (at some overlap, XY IoU <= 0.25): its place, its shape, either or
both (tools.breakdown.loose_causes).

With --true-poses the houses are ingested with the poses their images were rendered from instead
of the simulated localiser's (bench_ceiling.py, write_true_poses): what a perfect localiser, or a
perfect pose correction, would give.

    python benchmarks/bench_breakdown.py [--houses 4] [--laps 2] [--profile realistic] [--set k=v]... [--list]
        [--keep DIR] [--true-poses]
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402
import yaml  # noqa: E402

import bench_accuracy as acc  # noqa: E402
from bench_ceiling import write_true_poses  # noqa: E402
from ltc_cli.config import load_config  # noqa: E402
from ltc_cli.ingest.session import ingest  # noqa: E402
from ltc_cli.map.model import MERGED, REMOVED  # noqa: E402
from ltc_cli.map.store import load_map  # noqa: E402
from ltc_cli.recordings.groundtruth import read_ground_truth  # noqa: E402
from ltc_cli.tools.breakdown import (  # noqa: E402
    FN_CAUSES, FP_CAUSES, ID_CAUSES, LOOSE_CAUSES, false_positive_causes, id_change_causes, loose_causes,
    missed_causes, tally,
)
from ltc_cli.tools.evaluate import evaluate_map, ids_kept, map_objects  # noqa: E402
from ltc_cli.tools.simulate.house import House  # noqa: E402
from ltc_cli.tools.simulate.options import check_options  # noqa: E402
from ltc_cli.tools.simulate.phantoms import place_phantoms  # noqa: E402


def phantoms_of(lap_dir: Path) -> list[dict]:
    """The recurring false positives of a simulated recording, rebuilt from its seed and options as
    ``simulate`` places them (fixed over laps; never in the ground truth)."""
    sim = yaml.safe_load((lap_dir / "recording.yaml").read_text())["simulator"]
    opts = check_options({k: v for k, v in sim["options"].items() if k not in ("frames_per_room", "min_pixels")},
                         sim.get("profile", "benign"))
    seed = sim["seed"]
    house = House(sim["scene"], np.random.default_rng([seed, 0x5CE7E]), np.random.default_rng([seed, 0x512E]),
                  opts["size_variation"])
    out = []
    for p in place_phantoms(house, np.random.default_rng([seed, 0xFA47]), opts["phantoms_per_room"]):
        c, yaw, size, _ = p.boxes[0]
        out.append({"id": p.id, "class": p.cls, "center": c, "yaw": yaw, "size": size})
    return out


def removed_by_reason(smap) -> dict:
    """{"eq4" | "absent" | "picture" | "unconfirmed": [map objects as removed]} from the event log."""
    reasons = {}
    for e in smap.events:
        if e.kind != "removed":
            continue
        d = str(e.detail or "")
        reason = "absent" if d.startswith("other: clearly") else "eq4" if d.startswith("other") \
            else "picture" if d.startswith("picture") else "unconfirmed"
        reasons.setdefault(reason, []).append(e.object_id)
    return {k: map_objects(smap, np.array(sorted(set(v)), dtype=np.int64) - 1) for k, v in reasons.items()}


def status_name(smap):
    names = {REMOVED: "removed", MERGED: "merged"}
    return lambda mid: names.get(int(smap.objects.status[mid - 1]), "active")


def run_house(h: Path, laps: int, args):
    """[(res, kept, fp causes, fn causes, id causes, class names)] per lap of one house."""
    phantoms = phantoms_of(h / "lap1")
    out, earlier, seen, before = [], [], set(), None
    with tempfile.TemporaryDirectory() as tmp:
        m = Path(tmp) / "map.h5"
        if args.keep:
            args.keep.mkdir(parents=True, exist_ok=True)
            m = args.keep / f"{h.name}.h5"
            m.unlink(missing_ok=True)
        for lap in range(1, laps + 1):
            cfg = load_config(args.config, ["association.metric=vertex", "maintenance.policy=non-detection",
                                            *args.sets])
            ingest([h / f"lap{lap}"], m, cfg)
            gt = read_ground_truth(h / f"lap{lap}")
            smap = load_map(m)
            res = evaluate_map(smap, gt, earlier)
            seen |= {o["id"] for o in gt["objects"] if o.get("seen_pixels", 1) > 0}
            res["_seen"] = acc.seen_fn_counts(res, seen)
            objs = map_objects(smap)
            rem = removed_by_reason(smap)
            fp = false_positive_causes(res, objs, gt["objects"], phantoms)
            fn = missed_causes(res, objs, gt["objects"], seen, rem.get("eq4", []), rem.get("absent", []),
                               rem.get("unconfirmed", []), rem.get("picture", []))
            kept = None if before is None else ids_kept(before, res)
            ids = {} if kept is None else id_change_causes(before, res, status_name(smap), kept["lost_gt_ids"])
            names = {**{f"m{o['id']}": o["class"] for o in objs}, **{f"g{o['id']}": o["class"] for o in gt["objects"]}}
            out.append((res, kept, fp, fn, ids, names, loose_causes(res, objs, gt["objects"])))
            earlier.append(gt)
            before = res
    return out


def true_pose_house(h: Path, laps: int) -> Path:
    """The house's laps with the true poses, beside it in the cache (``<house>-truepose``)."""
    out = h.parent / f"{h.name}-truepose"
    for lap in range(1, laps + 1):
        if not (out / f"lap{lap}" / "poses.txt").is_file():
            write_true_poses(h / f"lap{lap}", out / f"lap{lap}")
    return out


def main():
    ap = acc.house_arguments()
    ap.add_argument("--list", action="store_true", help="print every error with its house, class and cause")
    ap.add_argument("--keep", type=Path, help="keep each house's map as DIR/<house>.h5 (after the last lap)")
    ap.add_argument("--true-poses", action="store_true", help="ingest with the poses the images were rendered from")
    args = ap.parse_args()
    houses = [acc.house(args.scene, args.first_seed + i, (), args.laps, args.profile) for i in range(args.houses)]
    if args.true_poses:
        houses = [true_pose_house(h, args.laps) for h in houses]
    print(f"{args.houses} '{args.scene}' houses ({args.profile}{', true poses' if args.true_poses else ''}), "
          f"config {args.config or 'defaults'}, overrides {args.sets or 'none'}")
    totals = [dict() for _ in range(args.laps)]
    strict = [dict() for _ in range(args.laps)]
    causes = [{"fp": [], "fn": [], "id": [], "loose": []} for _ in range(args.laps)]
    for h in houses:
        for lap, (res, kept, fp, fn, ids, names, loose) in enumerate(run_house(h, args.laps, args)):
            acc.add(totals[lap], res)
            acc.add_strict(strict[lap], res, kept)
            for key, d, prefix in (("fp", fp, "m"), ("fn", fn, "g"), ("id", ids, "g"), ("loose", loose, "g")):
                causes[lap][key] += [(h.name, i, names.get(f"{prefix}{i}", "?"), c) for i, c in d.items()]
    print(acc.STRICT_HEAD)
    for lap in range(args.laps):
        print(acc.row(f"lap {lap + 1} (any overlap)", totals[lap]))
        print(acc.strict_row(f"lap {lap + 1}", totals[lap], strict[lap]))
    for lap in range(args.laps):
        c = causes[lap]
        for key, names in (("fp", FP_CAUSES + ("misplaced",)), ("fn", FN_CAUSES + ("loose",)), ("id", ID_CAUSES),
                           ("loose", LOOSE_CAUSES)):
            t = tally({k: v[3] for k, v in enumerate(c[key])}, names)
            print(f"lap {lap + 1} {key}: " + ", ".join(f"{n} {t[n]}" for n in t))
        if args.list:
            for key in ("fp", "fn", "id", "loose"):
                for hname, i, cls, cause in sorted(c[key], key=lambda x: (x[3], x[0], x[1])):
                    print(f"  lap {lap + 1} {key} {cause:<14} {hname} {'map' if key == 'fp' else 'gt'} {i} {cls}")


if __name__ == "__main__":
    main()

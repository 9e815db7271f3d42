"""What is wrong in the map's boxes: each match after the last lap rescored with one part of the
truth put in (its yaw, its centre, or its size and yaw at the map's centre), median XY IoU by class;
then which way the sizes are off: the map's box over the truth's along the truth's long and short
footprint sides and its height (quartiles), and the footprint centres' distance.

Reads the maps that ``bench_breakdown.py --keep DIR`` kept (DIR/<house>.h5) and their houses in
benchmarks/.cache; the part whose truth lifts the IoU most is the part the map gets wrong.

    python benchmarks/bench_breakdown.py --houses 4 --scene medium --laps 2 --keep /tmp/kept
    python benchmarks/bench_box_errors.py /tmp/kept [more dirs]
"""

from __future__ import annotations

import argparse
import sys
from collections import defaultdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numpy as np  # noqa: E402

from ltc_cli.geometry.boxes import align_yaw  # noqa: E402
from ltc_cli.map.store import load_map  # noqa: E402
from ltc_cli.recordings.groundtruth import read_ground_truth  # noqa: E402
from ltc_cli.tools.evaluate import evaluate_map, map_objects, xy_iou  # noqa: E402

CACHE = Path(__file__).resolve().parent / ".cache"


def as_box(obj: dict) -> tuple:
    """(center (3,), yaw, size (3,)) of a map or ground-truth object."""
    return np.asarray(obj["center"], float), float(obj["yaw"]), np.asarray(obj["size"], float)


def rescored(mapped: tuple, truth: tuple) -> dict:
    """XY IoU of a map box (center (3,), yaw, size (3,)) against the truth's, as it is and with the
    truth's yaw (sides swapped when the two are nearer a quarter turn apart), centre, or size."""
    (c_m, yaw_m, s_m), (c_t, yaw_t, s_t) = mapped, truth
    s_turned = align_yaw(yaw_t, yaw_m, s_m)[1]
    return {"as mapped": xy_iou(mapped, truth), "truth's yaw": xy_iou((c_m, yaw_t, s_turned), truth),
            "truth's centre": xy_iou((c_t, yaw_m, s_m), truth), "truth's size": xy_iou((c_m, yaw_t, s_t), truth)}


def size_ratios(mapped: tuple, truth: tuple) -> tuple[float, float, float, float]:
    """(long, short, height, centre distance): the map box's sizes over the truth's, along the
    truth's longer and shorter footprint sides (the map box's sides taken in the quarter turn
    nearest the truth's yaw) and up, and the distance (m) between the footprints' centres."""
    (c_m, yaw_m, s_m), (c_t, yaw_t, s_t) = mapped, truth
    s_m = align_yaw(yaw_t, yaw_m, s_m)[1]
    long_axis = 0 if s_t[0] >= s_t[1] else 1
    r = s_m / s_t
    return float(r[long_axis]), float(r[1 - long_axis]), float(r[2]), float(np.hypot(*(c_m[:2] - c_t[:2])))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dirs", nargs="+", type=Path, help="folders of maps kept by bench_breakdown.py --keep")
    args = ap.parse_args(argv)
    rows, ratios = defaultdict(list), defaultdict(list)
    for folder in args.dirs:
        if not any(folder.glob("*.h5")):
            print(f"{folder}: no maps (*.h5) here; make them with bench_breakdown.py --keep", file=sys.stderr)
            return 1
        for path in sorted(folder.glob("*.h5")):
            laps = sorted((CACHE / path.stem).glob("lap*"))
            if not laps:
                print(f"{path}: no house {path.stem} in {CACHE}", file=sys.stderr)
                return 1
            truths = [read_ground_truth(lap) for lap in laps]
            smap = load_map(path)
            res = evaluate_map(smap, truths[-1], truths[:-1])
            mapped = {o["id"]: o for o in map_objects(smap)}
            truth = {o["id"]: o for o in truths[-1]["objects"]}
            for match in res["matches"]:
                t = truth[match["gt_id"]]
                boxes = as_box(mapped[match["map_id"]]), as_box(t)
                rows[t["class"]].append(rescored(*boxes))
                ratios[t["class"]].append(size_ratios(*boxes))
    keys = ["as mapped", "truth's yaw", "truth's centre", "truth's size"]
    print(f"{'class':<14}{'matches':>8}" + "".join(f"{k:>16}" for k in keys) + f"{'<= 0.25':>9}")
    everything = [r for rs in rows.values() for r in rs]
    for name, rs in sorted(rows.items(), key=lambda kv: -len(kv[1])) + [("all", everything)]:
        medians = "".join(f"{np.median([r[k] for r in rs]):16.2f}" for k in keys)
        print(f"{name:<14}{len(rs):>8}{medians}{sum(r['as mapped'] <= 0.25 for r in rs):>9}")
    for k in keys[1:]:
        print(f"at or under 0.25 with the {k}: {sum(r[k] <= 0.25 for r in everything)} of {len(everything)}")
    print()
    print(f"{'class':<14}{'matches':>8}" + "".join(f"{k:>18}" for k in ("long side", "short side", "height"))
          + f"{'centre off (m)':>18}   (map / truth, quartiles)")
    for name, rs in sorted(ratios.items(), key=lambda kv: -len(kv[1])):
        a = np.asarray(rs)
        cols = "".join(f"{'%.2f %.2f %.2f' % tuple(np.percentile(a[:, j], [25, 50, 75])):>18}" for j in range(4))
        print(f"{name:<14}{len(rs):>8}{cols}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

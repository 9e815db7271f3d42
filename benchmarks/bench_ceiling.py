"""How well could any mapper do on the realistic simulated houses, given only the localiser's error?

The realistic profile writes estimated poses (a slow drift of 4 cm and 1.5 degrees, plus jitter) in
poses.txt while it renders every image from the true ones. A mapper that modeled every object
perfectly from every view would still place each view's box where the estimated pose puts it. This
benchmark builds that perfect map and scores it with the same evaluator as the real one:

- for each ground-truth object of a lap and each frame where the annotations show it, the object's
  true box moved by that frame's pose error (a point seen from the true pose T_true is mapped
  through the estimated pose T_est: p -> T_est T_true^-1 p);
- the oracle box: those boxes' centres and yaw changes averaged over the frames, weighted by the
  object's annotated pixels (as fusing many views would), with the true size;
- with ``--laps-pooled``, an object that did not move between laps pools the frames of every lap so
  far (what a map that keeps its id does).

The share of oracle boxes at XY IoU > 0, > 0.25 and > 0.5 is the ceiling of precision and recall at
those thresholds (a map with one perfect box per seen object), per class and overall. The pose
errors are regenerated exactly from the recording's seed and lap (the simulator draws them from
its own generator, ltc_cli/tools/simulate/extras.py), so the figures are the simulator's, not a
model of it.

The detector bounds recall too: a mapper can only map an object its detector named. The last two
columns are the share of seen objects that the recorded detector found, with their own class, in
at least one and at least two frames while they stood where they stand now (a detection is on an
object when more than half of its mask lies on the object's annotated pixels). ltc keeps an object
only after two detections from distinct views, the paper after one.

    python benchmarks/bench_ceiling.py [--scene small] [--houses 4] [--first-seed 101] [--laps-pooled]
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import defaultdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import cv2  # noqa: E402
import numpy as np  # noqa: E402
import yaml  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402

import bench_accuracy as acc  # noqa: E402
from ltc_cli.recordings.groundtruth import read_ground_truth  # noqa: E402
from ltc_cli.recordings.rle import decode  # noqa: E402
from ltc_cli.tools.evaluate import pairwise_ious  # noqa: E402
from ltc_cli.tools.simulate.drift import pose_errors  # noqa: E402

POSE_STREAM = 0x10CA1  # the generator stream the simulator draws a lap's pose errors from


def pose_lines_and_errors(lap_dir: Path):
    """(poses.txt split into lines of fields, position errors (F, 3), rotation errors (F, 3) as
    world-frame rotation vectors) of one simulated lap: the localiser's error, redrawn."""
    meta = yaml.safe_load((lap_dir / "recording.yaml").read_text())["simulator"]
    lines = [ln.split() for ln in (lap_dir / "poses.txt").read_text().splitlines() if ln.strip()]
    d_pos, d_rot = pose_errors(np.random.default_rng([meta["seed"], meta["lap"], POSE_STREAM]), len(lines),
                               meta["options"])
    return lines, d_pos, d_rot


def write_true_poses(lap_dir: Path, out_dir: Path) -> None:
    """A copy of a simulated lap in ``out_dir`` whose poses.txt holds the true poses the images were
    rendered from (every other file a link to the original): the simulator's estimated pose is the
    true one with its rotation turned by the error about the camera centre, then moved by the
    position error (ltc_cli/tools/simulate/drift.py, estimated_poses), undone here."""
    out_dir.mkdir(parents=True, exist_ok=True)
    for f in lap_dir.iterdir():
        if f.name != "poses.txt" and not (out_dir / f.name).exists():
            (out_dir / f.name).symlink_to(f.resolve())
    lines, d_pos, d_rot = pose_lines_and_errors(lap_dir)
    rows = []
    for ln, dp, dr in zip(lines, d_pos, d_rot):
        t_true = np.array([float(x) for x in ln[1:4]]) - dp
        q_true = (Rotation.from_rotvec(dr).inv() * Rotation.from_quat([float(x) for x in ln[4:8]])).as_quat()
        rows.append(" ".join([ln[0], *(repr(float(x)) for x in (*t_true, *q_true))]))
    (out_dir / "poses.txt").write_text("\n".join(rows) + "\n")


def lap_views(lap_dir: Path):
    """(per-frame position errors (F, 3), rotation errors as Rotation (F,), true camera centres (F, 3),
    per-frame {object id: annotated pixels}, per-frame {object id: classes the detector gave it})
    of one simulated lap."""
    lines, d_pos, d_rot = pose_lines_and_errors(lap_dir)
    t_est_xyz = np.array([[float(x) for x in ln[1:4]] for ln in lines])
    pixels, named = [], []
    for ln in lines:
        ann = cv2.imread(str(lap_dir / "annotations" / f"{ln[0]}.png"), cv2.IMREAD_UNCHANGED)
        ids, counts = np.unique(ann, return_counts=True)
        pixels.append({int(i): int(c) for i, c in zip(ids, counts) if i > 0})
        named.append(detected_objects(ann, lap_dir / "detections" / f"{ln[0]}.json"))
    return d_pos, Rotation.from_rotvec(d_rot), t_est_xyz - d_pos, pixels, named


def detected_objects(ann_ids: np.ndarray, detections_json: Path) -> dict:
    """{object id: set of classes} of the detections of one frame whose masks lie more than half on
    one object's annotated pixels ann_ids (H, W). Looser than ``ltc calibrate``'s one-to-one IoU
    matching (tools/calibrate.py, match_frame) on purpose: a bound must not miss the halves of a
    split mask or a mask that bleeds onto the wall, which a mapper still turns into the object."""
    out: dict = defaultdict(set)
    if not detections_json.exists():
        return out
    for inst in json.loads(detections_json.read_text())["instances"]:
        on = ann_ids[decode(inst["mask"])]
        ids, counts = np.unique(on[on > 0], return_counts=True)
        if ids.size and counts.max() > 0.5 * on.size:
            out[int(ids[np.argmax(counts)])].add(inst["class"])
    return out


def oracle_box(obj: dict, views: list) -> tuple[np.ndarray, float] | None:
    """(centre (3,), yaw) of the perfect map box of ``obj``: its true box carried through each
    view's pose error, averaged with the annotated pixels as weights. views: (d_pos (3,), d_rot
    Rotation, true camera centre (3,), pixels). None when no view shows it."""
    centre = np.asarray(obj["center"], dtype=np.float64)
    moved, turned, weights = [], [], []
    for d_pos, d_rot, cam_true, px in views:
        # p_map = R_err (p - c_true) + c_true + d_pos: the rotation error turns about the camera.
        moved.append(d_rot.apply(centre - cam_true) + cam_true + d_pos)
        x_axis = d_rot.apply([np.cos(obj["yaw"]), np.sin(obj["yaw"]), 0.0])
        turned.append(np.arctan2(x_axis[1], x_axis[0]) - obj["yaw"])
        weights.append(px)
    if not weights:
        return None
    w = np.asarray(weights, dtype=np.float64)
    dyaw = np.angle(np.sum(w * np.exp(1j * np.asarray(turned)))).item()
    return np.average(np.asarray(moved), axis=0, weights=w), float(obj["yaw"] + dyaw)


def house_ceiling(house: Path, pooled: bool, laps: int = 2) -> list[tuple[str, float, int]]:
    """(class, oracle XY IoU, frames in which the detector named it) of every seen ground-truth
    object of the house's last lap (the frames of every lap while it stood where it stands now)."""
    found: dict = defaultdict(int)  # object id -> frames with a detection of its class on it
    history: dict = defaultdict(list)  # object id -> views of it while it stood where it stands now
    last_pose: dict = {}
    out = []
    for lap in range(1, laps + 1):
        lap_dir = house / f"lap{lap}"
        gt = read_ground_truth(lap_dir)
        d_pos, d_rot, cam_true, pixels, named = lap_views(lap_dir)
        for obj in gt["objects"]:
            pose = (tuple(np.round(obj["center"], 6)), round(obj["yaw"], 6))
            if last_pose.get(obj["id"]) != pose:
                found[obj["id"]] = 0
            if not pooled or last_pose.get(obj["id"]) != pose:
                history[obj["id"]] = []
            last_pose[obj["id"]] = pose
            found[obj["id"]] += sum(obj["class"] in frame.get(obj["id"], ()) for frame in named)
            for f, px in enumerate(pixels):
                if px.get(obj["id"], 0) > 0:
                    history[obj["id"]].append((d_pos[f], d_rot[f], cam_true[f], px[obj["id"]]))
        if lap < laps:
            continue
        for obj in gt["objects"]:
            box = oracle_box(obj, history[obj["id"]])
            if box is None:
                continue
            iou = pairwise_ious([(box[0], box[1], obj["size"])], [(obj["center"], obj["yaw"], obj["size"])])[0]
            out.append((obj["class"], float(iou[0, 0]), found[obj["id"]]))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default="small")
    ap.add_argument("--houses", type=int, default=4)
    ap.add_argument("--first-seed", type=int, default=101)
    ap.add_argument("--laps-pooled", action="store_true", help="an unmoved object pools the views of every lap")
    args = ap.parse_args()
    rows = []
    for i in range(args.houses):
        rows += house_ceiling(acc.house(args.scene, args.first_seed + i), args.laps_pooled)
    by_class = defaultdict(list)
    for cls, iou, n_found in rows:
        by_class[cls].append((iou, n_found))
    print(f"{args.houses} '{args.scene}' houses (realistic), lap 2, views {'of every lap' if args.laps_pooled else 'of lap 2'}:"
          " a perfect box per seen object, moved only by the pose error")
    print(f"{'class':16s} {'objects':>7s} {'mean IoU':>8s} {'> 0':>7s} {'> 0.25':>7s} {'> 0.5':>7s}"
          f" {'named':>7s} {'named 2':>7s}")
    for cls in sorted(by_class, key=lambda c: np.mean([iou for iou, _ in by_class[c]])):
        print(_row(cls, np.array(by_class[cls]), 2))
    print(_row("all", np.array([(iou, n) for _, iou, n in rows]), 3)
          + "   <- the ceiling of precision and recall at those IoU thresholds; of recall by the detector")


def _row(name: str, iou_found: np.ndarray, digits: int) -> str:
    """One table row from (N, 2) rows of (oracle IoU, frames the detector named the object in)."""
    v, n = iou_found[:, 0], iou_found[:, 1]
    shares = (np.mean(v > 0), np.mean(v > 0.25), np.mean(v > 0.5), np.mean(n >= 1), np.mean(n >= 2))
    return f"{name:16s} {len(v):7d} {v.mean():8.3f} " + " ".join(f"{x:7.{digits}f}" for x in shares)


if __name__ == "__main__":
    main()

"""What lap 1's depth says of the additions ``ltc changes`` reports after lap 2, on the simulated
two-lap houses of bench_paired.py's development sets (small 1-4, medium 101-104, realistic profile):
for each addition, the share of its box's image pixels over lap 1's frames (every other one) whose
depth ends inside the box (its bottom raised 5 cm: the floor under it is not it), against what the
simulator says it was: a thing lap 1 already held within 0.5 m ("was-there": lap 1's detector
missed it), a thing the simulator added within 1 m ("added"), or neither ("other").

A thing that stood there stops lap 1's rays in its box; an empty place lets them through. If the
two groups part, a session that kept where its depth ended (not only which floor cells it saw,
map/coverage.py) could tell a detector's miss from an addition. A measurement, not a rule of ltc.

    python benchmarks/bench_seen_before.py
"""

import os
import sys
import tempfile
from pathlib import Path

import numpy as np

os.environ.setdefault("OMP_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.bench_accuracy import house  # noqa: E402
from ltc_cli.config import load_config  # noqa: E402
from ltc_cli.geometry.boxes import Boxes  # noqa: E402
from ltc_cli.ingest.session import ingest  # noqa: E402
from ltc_cli.map.changes import map_changes  # noqa: E402
from ltc_cli.map.store import load_map  # noqa: E402
from ltc_cli.pipeline.visibility import occupied_pixels, pixel_counts  # noqa: E402
from ltc_cli.recordings.groundtruth import read_ground_truth  # noqa: E402
from ltc_cli.recordings.open import open_recording  # noqa: E402

HOUSES = (("small", range(1, 5)), ("medium", range(101, 105)))
SHARE = 0.15  # a bar the groups are counted against


def additions(scene: str, seed: int) -> list[tuple]:
    """(class, what it was, share of its pixels whose lap-1 depth ends inside it, pixels) per addition."""
    root = house(scene, seed)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "m.h5"
        for lap in ("lap1", "lap2"):
            ingest([root / lap], path, load_config(None, []))
        adds = [c for c in map_changes(load_map(path)).changes if c.kind == "added"]
    if not adds:
        return []
    gt1 = read_ground_truth(root / "lap1")["objects"]
    gt2 = read_ground_truth(root / "lap2")
    after = {o["id"]: o for o in gt2["objects"]}
    added_xy = [np.array(after[i]["center"][:2]) for i in (gt2.get("changes") or {}).get("added", []) if i in after]
    boxes = Boxes(np.array([c.center for c in adds]), np.array([c.yaw for c in adds]),
                  np.array([c.size for c in adds]), np.ones((len(adds), 8), bool))
    inside, image = np.zeros(len(adds)), np.zeros(len(adds))
    for ref in open_recording(root / "lap1").frames[::2]:
        f = ref.load()  # the simulator's world is z-up: its poses are the map frame's
        inside += occupied_pixels(boxes, f.T_world_camera, f.depth_m, f.intrinsics, 8, 0.0, 0.05)
        image += pixel_counts(boxes, f.T_world_camera, f.depth_m, f.intrinsics, 8, 0.2, (0.3, 6.0))[1]
    out = []
    for c, n_in, n_px in zip(adds, inside, image):
        was = any(g["class"] == c.cls and np.hypot(*(np.array(g["center"][:2]) - c.center[:2])) < 0.5 for g in gt1)
        new = any(np.hypot(*(a - c.center[:2])) < 1.0 for a in added_xy)
        out.append((c.cls, "was-there" if was else ("added" if new else "other"), n_in / max(n_px, 1), n_px))
    return out


def main() -> None:
    rows = [(scene, seed, *a) for scene, seeds in HOUSES for seed in seeds for a in additions(scene, seed)]
    for scene, seed, cls, what, share, px in sorted(rows, key=lambda r: (r[3], r[4])):
        print(f"{scene:6s} {seed:4d} {cls:12s} {what:10s} lap 1's depth ends inside it in {share:.2f} of {px:.0f} px")
    for what in ("added", "was-there", "other"):
        got = [r[4] for r in rows if r[3] == what]
        print(f"{what}: {len(got)} additions, {sum(v >= SHARE for v in got)} at a share of {SHARE} or more")


if __name__ == "__main__":
    main()

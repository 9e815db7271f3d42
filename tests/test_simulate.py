"""Tests of ltc_cli.simulate: geometry of the rendered data, determinism, formats, lap changes."""

import hashlib
import json
import math
from pathlib import Path

import jsonschema
import numpy as np
import pytest
import yaml
from PIL import Image

from ltc_cli.recordings import rle
from ltc_cli.errors import LtcError
from ltc_cli.geometry.camera import pose_matrix
from ltc_cli.tools.simulate import CLASSES, simulate
from ltc_cli.tools.simulate import House as _House
from ltc_cli.tools.simulate import camera_path as _path

SCHEMAS = Path(__file__).resolve().parents[1] / "schemas"
W, H = 160, 120
PERFECT = dict(
    depth_noise=0,
    depth_resolution=0,
    rgb_noise=0,
    miss_rate=0,
    confusion_rate=0,
    bleed_px=0,
    false_positive_rate=0,
    split_rate=0,
)


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    """A tiny house, two laps, no sensor noise and a perfect detector."""
    out = tmp_path_factory.mktemp("clean")
    return out, simulate(out, scene="tiny", laps=2, seed=3, width=W, height=H, **PERFECT)


@pytest.fixture(scope="module")
def noisy(tmp_path_factory):
    """A tiny house, two laps, default noise."""
    out = tmp_path_factory.mktemp("noisy")
    return out, simulate(out, scene="tiny", laps=2, seed=5, width=W, height=H)


def _png(path: Path) -> np.ndarray:
    with Image.open(path) as im:
        return np.array(im)


def _hashes(root: Path) -> dict:
    return {
        str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(root.rglob("*"))
        if p.is_file()
    }


def _read_poses(lap: Path) -> dict:
    poses = {}
    for line in (lap / "poses.txt").read_text().splitlines():
        fid, *vals = line.split()
        vals = [float(v) for v in vals]
        poses[fid] = pose_matrix(vals[:3], vals[3:])
    return poses


def _camera(lap: Path) -> dict:
    return yaml.safe_load((lap / "recording.yaml").read_text())["camera"]


def _gt(lap: Path) -> dict:
    return json.loads((lap / "ground_truth.json").read_text())


def test_backprojected_object_pixels_lie_in_their_boxes(clean):
    out, summary = clean
    for lap_no in (1, 2):
        lap = out / f"lap{lap_no}"
        cam = _camera(lap)
        poses = _read_poses(lap)
        boxes = {o["id"]: o for o in _gt(lap)["objects"]}
        checked = set()
        v, u = np.mgrid[0:H, 0:W]
        for fid, T in poses.items():
            depth = _png(lap / "depth" / f"{fid}.png").astype(np.float64) / 1000.0
            ann = _png(lap / "annotations" / f"{fid}.png")
            assert depth.shape == (H, W) and ann.shape == (H, W)
            for oid in np.unique(ann[ann > 0]).tolist():
                assert oid in boxes, f"frame {fid}: annotated id {oid} is not in ground_truth.json"
                sel = (ann == oid) & (depth > 0)
                if not sel.any():
                    continue
                z = depth[sel]
                # Eq. 1, then T_world_camera.
                pc = np.stack([z * (u[sel] - cam["cx"]) / cam["fx"], z * (v[sel] - cam["cy"]) / cam["fy"], z], 1)
                pw = pc @ T[:3, :3].T + T[:3, 3]
                b = boxes[oid]
                c, s = math.cos(b["yaw"]), math.sin(b["yaw"])
                d = pw - np.array(b["center"])
                local = np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], d[:, 2]], 1)
                excess = np.abs(local) - np.array(b["size"]) / 2
                assert excess.max() < 0.01, f"lap {lap_no} frame {fid} object {oid}: {excess.max():.4f} m out"
                checked.add(oid)
        # Most objects of the lap were seen and checked.
        assert len(checked) >= len(boxes) - 2


def test_ground_truth_boxes_follow_conventions(clean):
    out, _ = clean
    for o in _gt(out / "lap1")["objects"]:
        assert -math.pi / 2 <= o["yaw"] < math.pi / 2
        assert all(s > 0 for s in o["size"])
        # Furniture stands on the floor or on something: nothing floats below the floor.
        assert o["center"][2] - o["size"][2] / 2 >= -1e-9
        assert o["class"] in CLASSES


def test_perfect_detector_gives_the_visible_instances(clean):
    out, summary = clean
    lap = out / "lap1"
    gt = {o["id"]: o["class"] for o in _gt(lap)["objects"]}
    min_px = yaml.safe_load((lap / "recording.yaml").read_text())["simulator"]["options"]["min_pixels"]
    total = 0
    for det_file in sorted((lap / "detections").glob("*.json")):
        fid = det_file.stem
        ann = _png(lap / "annotations" / f"{fid}.png")
        doc = json.loads(det_file.read_text())
        got = sorted((i["class"], rle.decode(i["mask"]).tobytes()) for i in doc["instances"])
        ids, counts = np.unique(ann[ann > 0], return_counts=True)
        want = sorted((gt[i], (ann == i).tobytes()) for i, n in zip(ids.tolist(), counts.tolist()) if n >= min_px)
        assert got == want, f"frame {fid}"
        total += len(got)
    assert total > 10


def test_seen_counts_match_annotations(clean):
    out, _ = clean
    for lap in (out / "lap1", out / "lap2"):
        pixels, frames = {}, {}
        for f in sorted((lap / "annotations").glob("*.png")):
            ann = _png(f)
            ids, counts = np.unique(ann[ann > 0], return_counts=True)
            for i, n in zip(ids.tolist(), counts.tolist()):
                pixels[i] = pixels.get(i, 0) + n
                frames[i] = frames.get(i, 0) + 1
        for o in _gt(lap)["objects"]:
            assert o["seen_pixels"] == pixels.get(o["id"], 0)
            assert o["seen_frames"] == frames.get(o["id"], 0)


def test_same_seed_same_bytes_other_seed_differs(noisy, tmp_path):
    out, summary = noisy
    again = tmp_path / "again"
    assert simulate(again, scene="tiny", laps=2, seed=5, width=W, height=H)["frames_per_lap"] == summary["frames_per_lap"]
    first, second = _hashes(out), _hashes(again)
    assert first == second
    other = tmp_path / "other"
    simulate(other, scene="tiny", laps=1, seed=6, width=W, height=H)
    third = _hashes(other)
    for name in ("lap1/ground_truth.json", "lap1/poses.txt", "lap1/depth/000000.png", "lap1/detections/000003.json"):
        assert third[name] != first[name], name


def test_files_validate_and_decode(noisy):
    out, summary = noisy
    rec_schema = json.loads((SCHEMAS / "recording.schema.json").read_text())
    det_schema = json.loads((SCHEMAS / "detections.schema.json").read_text())
    gt_schema = json.loads((SCHEMAS / "ground_truth.schema.json").read_text())
    n_inst = 0
    for lap_no in (1, 2):
        lap = out / f"lap{lap_no}"
        meta = yaml.safe_load((lap / "recording.yaml").read_text())
        jsonschema.validate(meta, rec_schema)
        assert meta["camera"]["width"] == W and meta["camera"]["height"] == H
        assert meta["depth"] == {"scale": 1000.0, "min": 0.3, "max": 6.0}
        assert meta["classes"] == list(CLASSES)
        assert meta["simulator"]["scene"] == "tiny" and meta["simulator"]["lap"] == lap_no
        jsonschema.validate(_gt(lap), gt_schema)
        fids = [line.split()[0] for line in (lap / "poses.txt").read_text().splitlines()]
        assert fids == [f"{i:06d}" for i in range(summary["frames_per_lap"])]
        for fid in fids:
            rgb = _png(lap / "rgb" / f"{fid}.png")
            depth = _png(lap / "depth" / f"{fid}.png")
            ann = _png(lap / "annotations" / f"{fid}.png")
            assert rgb.dtype == np.uint8 and rgb.shape == (H, W, 3)
            assert depth.dtype == np.uint16 and depth.shape == (H, W) and depth.max() > 0
            assert ann.dtype == np.uint16 and ann.shape == (H, W)
            doc = json.loads((lap / "detections" / f"{fid}.json").read_text())
            jsonschema.validate(doc, det_schema)
            assert doc["frame"] == fid
            for inst in doc["instances"]:
                mask = rle.decode(inst["mask"])
                assert mask.shape == (H, W) and mask.any()
                assert 0.5 <= inst["score"] <= 0.99 and inst["class"] in CLASSES
                assert inst["scores"][inst["class"]] == inst["score"]
                assert sum(inst["scores"].values()) <= 1.0 + 1e-9
                n_inst += 1
    assert n_inst > 5


def test_poses_are_a_level_robot_camera(noisy):
    out, _ = noisy
    poses = _read_poses(out / "lap1")
    for T in poses.values():
        R = T[:3, :3]
        assert np.allclose(R.T @ R, np.eye(3), atol=1e-9)
        assert abs(T[2, 3] - 1.0) < 0.05  # camera height
        pitch = math.degrees(math.asin(-R[2, 2]))  # optical axis (camera z) below the horizon
        assert 7 < pitch < 17
    assert (out / "lap1" / "poses.txt").read_text() == (out / "lap2" / "poses.txt").read_text()


def test_lap_two_differs_by_the_recorded_changes(noisy):
    out, summary = noisy
    g1, g2 = _gt(out / "lap1"), _gt(out / "lap2")
    assert g1["changes"] == {"moved": [], "removed": [], "added": []}
    ch = g2["changes"]
    assert ch["moved"] and ch["removed"] and ch["added"]
    b1 = {o["id"]: o for o in g1["objects"]}
    b2 = {o["id"]: o for o in g2["objects"]}
    assert sorted(set(b1) - set(b2)) == ch["removed"]
    assert sorted(set(b2) - set(b1)) == ch["added"]
    assert not set(ch["added"]) & set(b1)  # new ids
    for oid in set(b1) & set(b2):
        same = all(b1[oid][k] == b2[oid][k] for k in ("center", "yaw", "size", "class"))
        assert same == (oid not in ch["moved"]), oid
        if oid in ch["moved"]:
            assert b1[oid]["class"] == b2[oid]["class"] and b1[oid]["size"] == b2[oid]["size"]
    assert summary["changes"][1] == ch
    assert summary["objects_per_lap"] == [len(b1), len(b2)]
    # Removed objects are never annotated in lap 2, added ones never in lap 1.
    for lap, absent in ((out / "lap2", ch["removed"]), (out / "lap1", ch["added"])):
        for f in (lap / "annotations").glob("*.png"):
            assert not np.isin(_png(f), absent).any()


def test_bad_arguments(tmp_path):
    for kwargs in (
        {"scene": "huge"},
        {"laps": 0},
        {"laps": 1.5},
        {"seed": -1},
        {"width": 8},
        {"miss_rate": 2},
        {"depth_noise": -0.1},
        {"colour": 3},
        {"frames_per_room": 0},
        {"bleed_px": "lots"},
    ):
        with pytest.raises(LtcError):
            simulate(tmp_path / "x", **{"scene": "tiny", **kwargs})
    assert not (tmp_path / "x").exists()


def test_refuses_non_empty_lap_folder(tmp_path):
    (tmp_path / "lap2").mkdir()
    (tmp_path / "lap2" / "keep.txt").write_text("mine")
    with pytest.raises(LtcError) as info:
        simulate(tmp_path, scene="tiny", laps=2, width=W, height=H)
    assert "lap2" in str(info.value)
    assert not (tmp_path / "lap1").exists()  # nothing written
    # An empty lap folder is fine.
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "lap1").mkdir()
    s = simulate(tmp_path / "empty", scene="tiny", laps=1, width=64, height=48, frames_per_room=3)
    assert s["frames_per_lap"] == 3 and (tmp_path / "empty" / "lap1" / "poses.txt").exists()


@pytest.mark.parametrize("scene,rooms", [("tiny", 1), ("small", 2), ("medium", 4), ("large", 6)])
def test_scenes_keep_the_path_clear(scene, rooms):
    """Every scene builds its rooms and furniture, and the camera never enters a piece of it."""
    house = _House(scene, np.random.default_rng([0, 1]))
    assert len(house.rooms) == rooms
    assert len(house.objects) >= 5 * rooms if rooms > 1 else len(house.objects) >= 6
    poses = _path(house, np.random.default_rng(0), 12, 0.8, 1.0, 12.0)
    assert len(poses) >= 12 * rooms
    footprints = [o.footprint() for o in house.objects.values()]
    for T in poses:
        p = T[:2, 3]
        for fp in footprints:
            # Distance from the camera to the footprint rectangle (0 inside).
            c = fp.mean(axis=0)
            ax = fp[1] - fp[0]
            ay = fp[3] - fp[0]
            lx, ly = np.linalg.norm(ax), np.linalg.norm(ay)
            d = p - c
            dx = max(0.0, abs(d @ ax / lx) - lx / 2)
            dy = max(0.0, abs(d @ ay / ly) - ly / 2)
            assert math.hypot(dx, dy) > 0.3


def test_last_lap_map_shows_ghosts_of_the_changes(noisy):
    """Lap 1's ground truth used as a stale map of lap 2: the moved and removed objects are
    ghosts, everything else matches exactly (the two modules agree on box conventions)."""
    from ltc_cli.tools.evaluate import evaluate

    out, _ = noisy
    g1, g2 = _gt(out / "lap1"), _gt(out / "lap2")
    r = evaluate(g1["objects"], g2, previous_gt=g1)
    ch = g2["changes"]
    stale = set(ch["moved"]) | set(ch["removed"])
    assert r["tp"] == len(g1["objects"]) - len(stale)
    assert all(m["xy_iou"] == pytest.approx(1.0) and m["position_error"] < 1e-9 for m in r["matches"])
    # A moved object whose old and new places overlap is matched (a TP) rather than a ghost.
    moved_matched = {m["map_id"] for m in r["matches"]} & set(ch["moved"])
    assert set(r["ghost_ids"]) == stale - moved_matched
    assert r["fn"] == len(ch["added"]) + len(set(ch["moved"]) - moved_matched)

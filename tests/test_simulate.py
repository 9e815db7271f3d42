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
from scipy.spatial.transform import Rotation

import ltc_cli.recordings.writer as rec_writer
from ltc_cli.recordings import rle
from ltc_cli.errors import LtcError
from ltc_cli.geometry.camera import pose_matrix
from ltc_cli.tools.simulate import CLASSES, simulate
from ltc_cli.tools.simulate import House as _House
from ltc_cli.tools.simulate import camera_path as _path
from ltc_cli.tools.simulate import DEFAULTS, PROFILES, House
from ltc_cli.tools.simulate.sensor import flying_pixels, holes
from ltc_cli.tools.simulate.views import SYSTEMATIC, ViewModel, cnn_mask

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


# -- the realistic profile (issue 9) ------------------------------------------------------------

REAL = PROFILES["realistic"]


@pytest.fixture(scope="module")
def realistic(tmp_path_factory):
    """The tiny house of the ``noisy`` fixture (same seed, size and path), realistic profile."""
    out = tmp_path_factory.mktemp("realistic")
    return out, simulate(out, scene="tiny", laps=2, seed=5, width=W, height=H, profile="realistic")


def _instances(lap: Path):
    """(frame id, annotation image, depth in metres, instances with decoded masks) per frame."""
    for det_file in sorted((lap / "detections").glob("*.json")):
        fid = det_file.stem
        insts = json.loads(det_file.read_text())["instances"]
        for inst in insts:
            inst["mask"] = rle.decode(inst["mask"])
        yield (fid, _png(lap / "annotations" / f"{fid}.png"),
               _png(lap / "depth" / f"{fid}.png").astype(np.float64) / 1000.0, insts)


def test_realistic_poses_drift_within_the_set_bounds(noisy, realistic):
    """poses.txt = the true pose (the benign run's, same seed) moved by the localiser's error: within
    2.5 std of the drift plus 3 std of the jitter on every axis, a few cm, slowly varying, and drawn
    anew every lap; the images still come from the true pose."""
    (bout, _), (rout, _) = noisy, realistic
    bound_xy = 2.5 * REAL["pose_drift_m"] + 3 * REAL["pose_jitter_m"]  # 0.115 m
    bound_yaw = math.radians(2.5 * REAL["pose_drift_deg"] + 3 * REAL["pose_jitter_deg"])  # 4.35 deg
    errors = []
    for lap in ("lap1", "lap2"):
        true, written = _read_poses(bout / lap), _read_poses(rout / lap)
        assert sorted(true) == sorted(written)
        e = np.array([written[f][:3, 3] - true[f][:3, 3] for f in sorted(true)])
        rotvec = np.array([(Rotation.from_matrix(written[f][:3, :3]) * Rotation.from_matrix(true[f][:3, :3]).inv())
                           .as_rotvec() for f in sorted(true)])
        assert np.abs(e[:, :2]).max() <= bound_xy + 1e-9
        assert np.abs(e[:, 2]).max() <= bound_xy / 4 + 1e-9
        assert np.abs(rotvec[:, 2]).max() <= bound_yaw + 1e-9
        assert np.abs(rotvec[:, :2]).max() <= bound_yaw / 3 + 1e-9
        rms = float(np.sqrt((e[:, :2] ** 2).sum(axis=1).mean()))
        assert 0.005 < rms  # a real error, not rounding
        # Slow: frame-to-frame changes are well under the error itself.
        step = float(np.sqrt((np.diff(e[:, :2], axis=0) ** 2).sum(axis=1).mean()))
        assert step < 0.5 * rms, (step, rms)
        errors.append(e)
    assert not np.allclose(errors[0], errors[1])
    # Rendered from the true pose: the same camera sees the walls and floor at the same depth (the
    # furniture differs: its sizes vary).
    for fid in ("000000", "000006"):
        d_b, d_r = (_png(o / "lap1" / "depth" / f"{fid}.png").astype(float) for o in (bout, rout))
        a_b, a_r = (_png(o / "lap1" / "annotations" / f"{fid}.png") for o in (bout, rout))
        both = (d_b > 0) & (d_r > 0) & (a_b == 0) & (a_r == 0)
        assert both.mean() > 0.3 and np.median(np.abs(d_b[both] - d_r[both])) < 30  # mm: sensor noise


def test_true_poses_undo_the_localisers_error(noisy, realistic, tmp_path):
    """benchmarks/bench_ceiling.py's write_true_poses on the realistic laps gives back the poses the
    images were rendered from: the benign run's (same seed, same path), to rounding; every other
    file is the realistic lap's own."""
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
    from bench_ceiling import write_true_poses

    (bout, _), (rout, _) = noisy, realistic
    for lap in ("lap1", "lap2"):
        write_true_poses(rout / lap, tmp_path / lap)
        true, undone, written = _read_poses(bout / lap), _read_poses(tmp_path / lap), _read_poses(rout / lap)
        assert sorted(undone) == sorted(true)
        for f in true:
            assert undone[f] == pytest.approx(true[f], abs=1e-9)
        assert max(np.abs(written[f][:3, 3] - true[f][:3, 3]).max() for f in true) > 0.01  # there was an error
        assert (tmp_path / lap / "ground_truth.json").resolve() == (rout / lap / "ground_truth.json").resolve()


def test_realistic_people_are_detected_and_never_ground_truth(realistic):
    out, _ = realistic
    schema = json.loads((SCHEMAS / "ground_truth.schema.json").read_text())
    det_schema = json.loads((SCHEMAS / "detections.schema.json").read_text())
    person_frames = 0
    for lap in (out / "lap1", out / "lap2"):
        meta = yaml.safe_load((lap / "recording.yaml").read_text())
        assert meta["simulator"]["profile"] == "realistic" and "person" in meta["classes"]
        gt = _gt(lap)
        jsonschema.validate(gt, schema)
        assert all(o["class"] != "person" for o in gt["objects"])
        ids = {o["id"] for o in gt["objects"]}
        for fid, ann, depth, insts in _instances(lap):
            assert set(np.unique(ann[ann > 0]).tolist()) <= ids  # people and phantoms not annotated
            jsonschema.validate(json.loads((lap / "detections" / f"{fid}.json").read_text()), det_schema)
            for inst in insts:
                if inst["class"] == "person" and (ann[inst["mask"]] == 0).mean() > 0.5:
                    # A person is a moving thing with depth, standing inside the room.
                    assert (depth[inst["mask"]] > 0).mean() > 0.3
                    person_frames += 1
    assert person_frames >= 2


def test_realistic_same_seed_same_bytes(realistic, tmp_path):
    out, _ = realistic
    again = tmp_path / "again"
    simulate(again, scene="tiny", laps=2, seed=5, width=W, height=H, profile="realistic")
    assert _hashes(again) == _hashes(out)
    other = tmp_path / "other"
    simulate(other, scene="tiny", laps=1, seed=6, width=W, height=H, profile="realistic")
    assert _hashes(other)["lap1/poses.txt"] != _hashes(out)["lap1/poses.txt"]


def test_benign_profile_is_the_default_and_writes_no_realism(noisy):
    out, _ = noisy
    meta = yaml.safe_load((out / "lap1" / "recording.yaml").read_text())
    assert "profile" not in meta["simulator"]
    assert "people_per_room" not in meta["simulator"]["options"] and "person" not in meta["classes"]


@pytest.fixture(scope="module")
def phantom_lap(tmp_path_factory):
    """One long lap of the tiny house, realistic, with two phantoms (a poster and clutter), no
    people and no one-off false positives: every detection mostly off the annotated objects is a
    phantom's."""
    out = tmp_path_factory.mktemp("phantoms")
    simulate(out, scene="tiny", laps=1, seed=5, width=W, height=H, profile="realistic", frames_per_room=40,
             people_per_room=0, false_positive_rate=0, split_rate=0, phantoms_per_room=2)
    return out / "lap1"


def test_realistic_phantoms_recur_at_one_place(phantom_lap):
    lap = phantom_lap
    cam = _camera(lap)
    poses = _read_poses(lap)
    v, u = np.mgrid[0:H, 0:W]
    found = {}
    for fid, ann, depth, insts in _instances(lap):
        for inst in insts:
            m = inst["mask"]
            if (ann[m] > 0).mean() >= 0.3:
                continue
            sel = m & (depth > 0)
            z = depth[sel]
            pc = np.stack([z * (u[sel] - cam["cx"]) / cam["fx"], z * (v[sel] - cam["cy"]) / cam["fy"], z], 1)
            T = poses[fid]
            found.setdefault(inst["class"], []).append((fid, np.median(pc @ T[:3, :3].T + T[:3, 3], axis=0)))
    # A poster taken for a tv and clutter taken for a book, each in several frames, always at the
    # same place (within the localiser's error and the mask's spread): not one-off blobs.
    assert {"tv", "book"} <= set(found), found.keys()
    for cls in ("tv", "book"):
        frames = {f for f, _ in found[cls]}
        assert len(frames) >= 4, (cls, frames)
        pts = np.array([p for _, p in found[cls]])
        assert np.linalg.norm(pts - np.median(pts, axis=0), axis=1).max() < 0.35


def _detection_states(lap: Path, min_px: int) -> dict:
    """{object id: [(frame index, detected?)]} over the frames where it has min_px annotated pixels;
    detected = some instance's mask is exactly its annotated pixels (masks are exact here)."""
    states = {}
    for k, (fid, ann, _, insts) in enumerate(_instances(lap)):
        masks = [inst["mask"] for inst in insts]
        ids, counts = np.unique(ann[ann > 0], return_counts=True)
        for oid, n in zip(ids.tolist(), counts.tolist()):
            if n >= min_px:
                hit = any(np.array_equal(m, ann == oid) for m in masks)
                states.setdefault(oid, []).append((k, hit))
    return states


MISSES = dict(PERFECT, miss_rate=0.15, class_miss=1.0, oblique_miss=REAL["oblique_miss"])


@pytest.fixture(scope="module")
def miss_laps(tmp_path_factory):
    """Two long laps of the tiny house whose only detector noise is misses with per-class rates:
    independent per frame, and correlated over nearby views."""
    out = tmp_path_factory.mktemp("misses")
    common = dict(scene="tiny", laps=2, seed=8, width=W, height=H, frames_per_room=72, **MISSES)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(rec_writer, "PNG_LEVEL", 1)  # fast PNGs: same pixels
        simulate(out / "indep", **common)
        simulate(out / "corr", view_correlation=0.95, **common)
    return [out / "indep" / f"lap{k}" for k in (1, 2)], [out / "corr" / f"lap{k}" for k in (1, 2)]


def _min_pixels(lap: Path) -> int:
    return yaml.safe_load((lap / "recording.yaml").read_text())["simulator"]["options"]["min_pixels"]


def test_realistic_tvs_are_missed_more_often_than_chairs(miss_laps):
    rate = {}
    for lap in miss_laps[0]:
        gt = {o["id"]: o["class"] for o in _gt(lap)["objects"]}
        for oid, seq in _detection_states(lap, _min_pixels(lap)).items():
            seen, missed = rate.get(gt[oid], (0, 0))
            rate[gt[oid]] = (seen + len(seq), missed + sum(not h for _, h in seq))
    tv, chair = (rate[c][1] / rate[c][0] for c in ("tv", "chair"))
    # tv: 2x the base rate plus up to oblique_miss when seen at an angle; chair: the base rate.
    assert rate["tv"][0] >= 20 and rate["chair"][0] >= 40, rate
    assert tv > chair + 0.15, (rate, tv, chair)


def test_realistic_misses_persist_over_nearby_views(miss_laps):
    """Far fewer switches between detected and missed from one view of an object to the next."""
    result = []
    for laps in miss_laps:
        switches = pairs = 0
        for lap in laps:
            for seq in _detection_states(lap, _min_pixels(lap)).values():
                for (k0, h0), (k1, h1) in zip(seq[:-1], seq[1:]):
                    if k1 == k0 + 1:
                        pairs += 1
                        switches += h0 != h1
        result.append(switches / pairs)
    assert pairs > 100 and result[1] < 0.6 * result[0], result


def test_correlated_draws_stay_uniform():
    """The correlated draw is uniform whatever the correlation (so every rate is unchanged), and
    consecutive frames' draws of one object agree far more with it than without."""
    n_obj, n_frames = 300, 40
    things = {i: ("chair", "object", np.zeros(3), 0.0) for i in range(1, n_obj + 1)}
    u_all = {}
    for rho in (0.0, 0.9):
        opts = dict(DEFAULTS, view_correlation=rho)
        model = ViewModel(opts, seed=1, lap=1, n_frames=n_frames, things=things)
        rng = np.random.default_rng(2)
        u = np.array([[model.frame(k, np.eye(4), rng).uniform(i, rng.uniform(), 0) for k in range(n_frames)]
                      for i in things])
        hist = np.histogram(u, bins=10, range=(0, 1))[0] / u.size
        assert np.abs(hist - 0.1).max() < 0.02, (rho, hist)  # 12000 draws: 0.1 +- 0.003 std
        u_all[rho] = u
    lag = {rho: np.corrcoef(u[:, :-1].ravel(), u[:, 1:].ravel())[0, 1] for rho, u in u_all.items()}
    assert abs(lag[0.0]) < 0.05 and lag[0.9] > 0.6, lag


def test_realistic_systematic_mislabels_use_one_other_class(tmp_path):
    """Every object with a systematic other class (mislabel_objects = 1) is called by it in some
    views and by its own class in the others, never by a third class (no other confusion here)."""
    simulate(tmp_path, scene="tiny", laps=1, seed=2, width=W, height=H, frames_per_room=30,
             **dict(PERFECT, mislabel_objects=1.0, mislabel_share=0.4))
    lap = tmp_path / "lap1"
    gt = {o["id"]: o["class"] for o in _gt(lap)["objects"]}
    labels = {}
    for _, ann, _, insts in _instances(lap):
        for inst in insts:
            oid = int(np.bincount(ann[inst["mask"]]).argmax())
            labels.setdefault(oid, []).append(inst["class"])
    table = next(i for i, c in gt.items() if c == "dining table")
    assert set(labels[table]) == {"dining table", "book"}  # a table called book in some views
    for oid, seen in labels.items():
        assert set(seen) <= {gt[oid], SYSTEMATIC[gt[oid]]}
        if len(seen) >= 6:
            assert 0 < seen.count(SYSTEMATIC[gt[oid]]) < len(seen), (gt[oid], seen)


def test_cnn_mask_fills_a_chair_back_and_drops_its_legs():
    m = np.zeros((120, 160), bool)
    m[60:64, 40:80] = True  # seat
    m[64:100, 40:43] = m[64:100, 77:80] = True  # legs, 3 px wide
    m[20:60, 40:43] = m[20:60, 77:80] = True  # back posts
    m[20:25, 40:80] = m[38:42, 40:80] = True  # top and middle rails
    c = cnn_mask(m)
    assert c[30, 45:75].all() and c[50, 45:75].all()  # the gaps of the back are filled
    assert not c[80:100, 40:43].any() and not c[80:100, 77:80].any()  # the legs are gone
    assert c[62, 45:75].all()  # the seat stays
    assert not c[:15].any() and not c[:, :35].any() and not c[:, 85:].any()  # no growth beyond the box


def test_depth_edges_fly_and_dark_surfaces_lose_readings():
    rng = np.random.default_rng(0)
    z = np.where(np.arange(40)[None, :] < 20, 1.0, 3.0) * np.ones((30, 1))
    hit = np.ones_like(z, dtype=bool)
    f = flying_pixels(rng, z, hit, 1.0)
    edge = np.zeros_like(hit)
    edge[:, 19:21] = True
    assert ((f[edge] > 1.0) & (f[edge] < 3.0)).all()  # between the two surfaces, in the air
    assert (f[~edge] == z[~edge]).all()
    p = np.zeros((120, 160))
    p[:, 80:] = 0.5
    lost = holes(rng, p)
    assert not lost[:, :80].any()
    assert 0.35 < lost[:, 80:].mean() < 0.65
    assert holes(rng, np.ones((20, 20))).all()


def test_realistic_sizes_vary_within_a_class():
    """A fridge is always 0.75 m deep (0.7 m body + handle) in the benign house, and within
    +-size_variation of that with it."""
    v = REAL["size_variation"]
    depths = {0.0: [], v: []}
    for seed in range(6):
        for var in depths:
            house = House("small", np.random.default_rng([seed, 1]), np.random.default_rng([seed, 2]), var)
            depths[var] += [o.box()[2][0] for o in house.objects.values() if o.cls == "refrigerator"]
    assert len(depths[0.0]) >= 4 and np.allclose(depths[0.0], 0.75)
    assert all(0.75 * (1 - v) - 1e-9 <= d <= 0.75 * (1 + v) + 1e-9 for d in depths[v])
    assert np.ptp(depths[v]) > 0.05


def test_cli_profile_default_is_realistic(tmp_path):
    from click.testing import CliRunner

    from ltc_cli.cli import cli

    for args, profile in (([], "realistic"), (["--profile", "benign"], None)):
        out = tmp_path / (profile or "benign")
        r = CliRunner().invoke(cli, ["simulate", str(out), "--scene", "tiny", "--laps", "1", "--width", "64",
                                     "--height", "48", "--set", "frames_per_room=3", *args])
        assert r.exit_code == 0, r.output
        meta = yaml.safe_load((out / "lap1" / "recording.yaml").read_text())
        assert meta["simulator"].get("profile") == profile


@pytest.mark.parametrize("kwargs", [{"profile": "harsh"}, {"cnn_masks": 0.5}, {"view_correlation": 1.5},
                                    {"drift_frames": 0}, {"people_per_room": -1}, {"pose_drift_m": -0.1}])
def test_bad_realism_options(tmp_path, kwargs):
    with pytest.raises(LtcError):
        simulate(tmp_path / "x", scene="tiny", **kwargs)
    assert not (tmp_path / "x").exists()

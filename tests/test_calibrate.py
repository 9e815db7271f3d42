"""ltc calibrate: the bookkeeping of TP / FP / FN / confusion, the recovery of a simulated detector's
miss rate, the calibration file, and the effect of v_Other on how fast removed objects leave a map."""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from PIL import Image

import ltc_cli.recordings.writer as rec_writer
import ltc_cli.tools.simulate as sim
from ltc_cli.recordings import rle
from ltc_cli.tools.calibrate import calibrate, match_frame, scaled_min_pixels, write_calibration
from ltc_cli.cli import cli
from ltc_cli.tools.calibration_file import load_calibration
from ltc_cli.map.store import load_map
from ltc_cli.validation import validate


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


# -- exact bookkeeping on a hand-made recording ----------------------------------------------------

W, H = 64, 48


def rect(u0, u1, v0, v1):
    m = np.zeros((H, W), dtype=bool)
    m[v0:v1, u0:u1] = True
    return m


def write_small_recording(root: Path, instances, detections, classes):
    """One frame: annotation ids from ``instances`` {id: (class, mask)}, recorded detections
    [(class, mask)]."""
    for sub in ("rgb", "depth", "detections", "annotations"):
        (root / sub).mkdir(parents=True, exist_ok=True)
    meta = {"format": "ltc-recording/1",
            "camera": {"width": W, "height": H, "fx": 50.0, "fy": 50.0, "cx": 31.5, "cy": 23.5},
            "depth": {"scale": 1000.0}, "classes": classes}
    (root / "recording.yaml").write_text(yaml.safe_dump(meta))
    (root / "poses.txt").write_text("000000 0 0 0 0 0 0 1\n")
    Image.fromarray(np.zeros((H, W, 3), np.uint8)).save(root / "rgb" / "000000.png")
    Image.fromarray(np.full((H, W), 2000, np.uint16)).save(root / "depth" / "000000.png")
    ann = np.zeros((H, W), np.uint16)
    for oid, (_, mask) in instances.items():
        ann[mask] = oid
    Image.fromarray(ann).save(root / "annotations" / "000000.png")
    doc = {"frame": "000000", "instances": [{"class": c, "score": 0.8, "mask": rle.encode(m)} for c, m in detections]}
    (root / "detections" / "000000.json").write_text(json.dumps(doc))
    gt = {"format": "ltc-ground-truth/1", "objects": [
        {"id": oid, "class": c, "center": [0, 0, 0], "yaw": 0.0, "size": [1, 1, 1]} for oid, (c, _) in instances.items()]}
    (root / "ground_truth.json").write_text(json.dumps(gt))
    return root


def test_counts_confusion_and_ignored_instances(tmp_path):
    chair, couch, tv = rect(0, 10, 0, 10), rect(20, 30, 0, 10), rect(40, 50, 0, 10)
    cup, lamp = rect(0, 5, 30, 34), rect(20, 30, 30, 40)
    instances = {1: ("chair", chair), 2: ("couch", couch), 3: ("tv", tv), 4: ("cup", cup), 5: ("lamp", lamp)}
    detections = [
        ("chair", chair),                       # TP
        ("chair", rect(0, 10, 2, 10)),          # IoU 0.8 with the chair, which is taken: a duplicate (FP)
        ("chair", rect(20, 30, 1, 10)),         # the couch, called a chair: confusion, FN couch, FP chair
        ("cup", cup),                           # a 20-pixel cup: under min_pixels, ignored (not a FP)
        ("tv", lamp),                           # on the lamp, a class the detector does not know: ignored
        ("bowl", rect(55, 64, 38, 48)),         # on the background: FP
    ]
    rec = write_small_recording(tmp_path / "rec", instances, detections, ["chair", "couch", "tv", "cup", "bowl"])
    cal = calibrate(rec, "recorded", min_pixels=50)
    s = cal.per_class
    assert (s["chair"].instances, s["chair"].detected, s["chair"].tp, s["chair"].fp, s["chair"].fn) == (1, 1, 1, 2, 0)
    assert (s["couch"].instances, s["couch"].detected, s["couch"].tp, s["couch"].fp, s["couch"].fn) == (1, 1, 0, 0, 1)
    assert (s["tv"].instances, s["tv"].detected, s["tv"].tp, s["tv"].fn) == (1, 0, 0, 1)
    assert (s["bowl"].instances, s["bowl"].fp) == (0, 1)
    assert "cup" not in s and "lamp" not in s
    assert cal.confusion == {"chair": {"chair": 1}, "couch": {"chair": 1}, "tv": {"missed": 1},
                             "background": {"bowl": 1, "chair": 1}}
    assert cal.ignored_instances == 2 and cal.ignored_detections == 2
    assert cal.recall == pytest.approx(1 / 3) and cal.precision == pytest.approx(1 / 4)
    assert cal.detection_rate == pytest.approx(2 / 3) and cal.v_other == pytest.approx(2 / 3)
    doc = write_calibration(cal, tmp_path / "cal.yaml")
    assert doc["tp"] == 1 and doc["fp"] == 3 and doc["fn"] == 2
    assert doc["per_class"]["bowl"]["recall"] is None  # 0/0 is written as null
    assert load_calibration(tmp_path / "cal.yaml")["v_other"] == pytest.approx(0.6667, abs=1e-4)


def test_match_frame_is_greedy_by_iou():
    ids = np.zeros((H, W), np.int64)
    ids[0:10, 0:10] = 7
    ids[0:10, 10:20] = 9
    a = rect(0, 12, 0, 10)   # IoU 100/120 with 7, 20/120 with 9
    b = rect(0, 10, 0, 10)   # IoU 1 with 7: it takes 7 first
    gt_ids, px, pairs = match_frame(ids, [a, b], 0.5)
    assert gt_ids.tolist() == [7, 9] and px.tolist() == [100, 100]
    assert pairs == [(1, 0, 1.0)]  # a is left unmatched: 9 is under the threshold for it


def test_min_pixels_scales_with_the_image_area():
    assert scaled_min_pixels(1000, 640, 480) == 1000
    assert scaled_min_pixels(1000, 320, 240) == 250
    assert scaled_min_pixels(1000, 160, 120) == 62  # 62.5 rounds to even


# -- the simulator's miss rate is recovered --------------------------------------------------------

MISS = 0.3
SIM_OPTS = dict(miss_rate=MISS, confusion_rate=0, bleed_px=0, false_positive_rate=0, split_rate=0,
                # No pixel minimum in the simulated detector, so no "small" multiplier on counted
                # instances; no depth beyond 3 m, so no "far" multiplier: an instance's miss
                # probability is MISS * (1 + 2 (1 - visible fraction)), exactly.
                min_pixels=1, max_range=3.0, rgb_noise=0, depth_noise=0)


@pytest.fixture(scope="module")
def noiseless(tmp_path_factory):
    """A simulated recording whose only detector noise is misses, with the renderer's per-frame
    visibility statistics captured to compute each instance's miss probability independently."""
    out = tmp_path_factory.mktemp("sim")
    stats = []
    render = sim.Renderer.render

    def capture(self, *args, **kw):
        res = render(self, *args, **kw)
        stats.append(res[3])
        return res

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(rec_writer, "PNG_LEVEL", 1)  # fast PNGs: same pixels
        mp.setattr(sim.Renderer, "render", capture)
        sim.simulate(out, scene="small", laps=1, seed=3, width=160, height=120, frames_per_room=200, **SIM_OPTS)
    rec = out / "lap1"
    return rec, stats


def miss_probability(n, full_n, bounds, w, h):
    """The simulator's rule (ltc_cli.simulate._detect) restated for the options above."""
    bu0, bu1, bv0, bv1 = bounds
    area = max(1e-9, (bu1 - bu0) * (bv1 - bv0))
    in_img = max(0.0, min(bu1, w) - max(bu0, 0)) * max(0.0, min(bv1, h) - max(bv0, 0))
    visible = min(1.0, n / max(full_n, 1)) * min(1.0, in_img / area)
    return min(0.97, MISS * (1 + 2.0 * (1 - visible)))


def test_recall_recovers_the_simulated_miss_rate(noiseless):
    rec, stats = noiseless
    cal = calibrate(rec, "recorded")
    assert cal.min_pixels == 62  # 1000 px at 640x480, scaled to 160x120
    frames = sorted(p.stem for p in (rec / "annotations").glob("*.png"))
    assert cal.frames == len(frames) == len(stats)
    # Exact bookkeeping: with no bleed, split, confusion or false positive, an instance is detected
    # iff the recorded detections hold exactly its mask.
    p_miss, detected, outcome = [], 0, {}
    for i, fid in enumerate(frames):
        ann = np.asarray(Image.open(rec / "annotations" / f"{fid}.png")).astype(np.int64)
        dets = json.loads((rec / "detections" / f"{fid}.json").read_text())["instances"]
        masks = [rle.decode(d["mask"]) for d in dets]
        ids, counts = np.unique(ann[ann > 0], return_counts=True)
        for oid, n in zip(ids.tolist(), counts.tolist()):
            if n < cal.min_pixels:
                continue
            hit = any(np.array_equal(m, ann == oid) for m in masks)
            detected += hit
            full_n, bounds = stats[i][oid]
            p_miss.append(miss_probability(n, full_n, bounds, 160, 120))
            outcome[(fid, oid)] = hit
    p = np.array(p_miss)
    t = cal.total
    assert t.instances == len(p) > 500
    assert t.detected == t.tp == detected and t.fp == 0 and cal.precision == 1.0
    assert cal.recall == cal.detection_rate and cal.v_other == pytest.approx(cal.recall)
    assert all(set(row) <= {name, "missed"} for name, row in cal.confusion.items())
    # Statistics: the measured recall is the simulator's expected detection probability, within
    # three standard errors of the Bernoulli draws (about 0.02 here).
    expected = float(np.mean(1 - p))
    se = float(np.sqrt(np.sum(p * (1 - p))) / len(p))
    assert abs(cal.recall - expected) < 3 * se, (cal.recall, expected, se)
    # ... and on the fully visible instances, where the miss probability is exactly MISS, it is 1 - MISS.
    full = [o for o in cal.instances if o.counted and np.isclose(p_miss_of(o, stats, frames), MISS)]
    rate = np.mean([o.detected_class is not None for o in full])
    assert len(full) > 100
    assert abs(rate - (1 - MISS)) < 3 * np.sqrt(MISS * (1 - MISS) / len(full)), (rate, len(full))
    assert all((o.detected_class is not None) == outcome[(o.frame, o.gt_id)] for o in cal.instances if o.counted)


def p_miss_of(o, stats, frames):
    full_n, bounds = stats[frames.index(o.frame)][o.gt_id]
    return miss_probability(o.pixels, full_n, bounds, 160, 120)


# -- the CLI, and what v_Other does to a map -------------------------------------------------------


@pytest.fixture(scope="module")
def house(tmp_path_factory):
    """Two laps of the tiny house; three of its seven objects are gone in lap 2."""
    out = tmp_path_factory.mktemp("house")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(rec_writer, "PNG_LEVEL", 1)
        summary = sim.simulate(out, scene="tiny", laps=2, seed=1, width=320, height=240, frames_per_room=30,
                               miss_rate=0.1, moved_fraction=0, added_fraction=0, removed_fraction=0.4)
    return out, summary


def test_cli_writes_a_calibration_that_ingest_reads(house, tmp_path):
    out, _ = house
    cal_path = tmp_path / "calibration.yaml"
    r = run("calibrate", out / "lap1", "--detector", "recorded", "-o", cal_path, "--table")
    assert r.exit_code == 0, r.output
    last = r.stdout.strip().splitlines()[-1]
    assert last.startswith(f"{cal_path}: 30 frames, ") and ", v_other " in last and "recall " in last
    doc = yaml.safe_load(cal_path.read_text())
    validate(doc, "calibration", cal_path)
    assert doc["format"] == "ltc-calibration/1" and doc["detector"] == "recorded" and doc["frames"] == 30
    assert doc["min_pixels"] == 250 and doc["instances"] > 0
    assert doc["v_other"] == pytest.approx(min(0.95, max(0.05, doc["detection_rate"])), abs=1e-4)
    assert set(doc["confusion"]) - {"background"} <= set(doc["per_class"])
    for name, s in doc["per_class"].items():
        assert s["tp"] + s["fn"] == s["instances"], name
        assert 0 < s["v_other"] < 1 if s["instances"] else s["v_other"] is None
    assert "docs/calibration.md" in doc["method"]
    assert load_calibration(cal_path)["v_other"] == doc["v_other"]
    assert not list(tmp_path.glob(".calibration.yaml.tmp*"))
    # The pixel minimum is honoured (no instance covers 70000 of 76800 pixels).
    r = run("calibrate", out / "lap1", "-o", tmp_path / "c2.yaml", "--min-pixels", "70000")
    assert r.exit_code == 1 and "no ground-truth instance with at least 70000 visible pixels" in r.stderr


def test_cli_errors_are_one_line(house, tmp_path):
    out, _ = house
    bare = tmp_path / "bare"
    shutil.copytree(out / "lap1", bare, ignore=shutil.ignore_patterns("annotations"))
    for args, text in [
        ([bare], "no annotations/ folder: calibrate needs ground-truth instance masks"),
        ([out / "lap1", "--detector", "nope"], "unknown detector 'nope'"),
        ([tmp_path / "missing"], "recording does not exist"),
        ([out / "lap1", "--set", "detector.options.folder=/nowhere"], "no detections/ folder"),
    ]:
        r = run("calibrate", *args, "-o", tmp_path / "c.yaml")
        lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
        assert r.exit_code == 1 and len(lines) == 1 and text in lines[0], r.stderr
        assert "Traceback" not in r.output
    (bare / "annotations").mkdir()
    (bare / "ground_truth.json").unlink()
    r = run("calibrate", bare, "-o", tmp_path / "c.yaml")
    assert r.exit_code == 1 and "no ground_truth.json" in r.stderr
    assert not (tmp_path / "c.yaml").exists()


def test_many_frames_skipped_for_one_reason_are_listed_ten_times(house, tmp_path):
    """12 of lap 1's annotated frames lack their depth image: calibrate warns for the first 10, says
    at the 11th that the rest are only counted, skips all 12 and measures the other 18."""
    out, _ = house
    part = tmp_path / "part"
    shutil.copytree(out / "lap1", part)
    gone = sorted((part / "depth").glob("*.png"))[:12]
    for p in gone:
        p.unlink()
    r = run("calibrate", part, "-o", tmp_path / "c.yaml")
    assert r.exit_code == 0, r.output
    lines = [ln for ln in r.stderr.splitlines() if ln.startswith("warning: skipped")]
    assert len(lines) == 11, lines
    for p, line in zip(gone[:10], lines[:10]):
        assert line == f"warning: skipped frame {p.stem}: {p}: image file is missing"
    assert lines[10] == (f"warning: skipped frame {gone[10].stem}: {gone[10]}: image file is missing; "
                         'further frames skipped for "image file is missing" are counted in the summary, not listed')
    assert r.stdout.startswith(f"{tmp_path / 'c.yaml'}: 18 frames (12 skipped: 12 image file is missing), ")
    doc = yaml.safe_load((tmp_path / "c.yaml").read_text())
    assert doc["frames_skipped"] == 12 and doc["frames"] == 18


def removal_record(map_path, gt_removed_centers):
    """For each removed ground-truth object (XY centre), the map object at it (active after lap 1)
    and, in session 1, the frame and the number of non-detections at which it was removed (None:
    never)."""
    smap = load_map(map_path)
    t = smap.objects
    rows = [r for r in range(len(t.status)) if t.first_session[r] == 0]
    out = {}
    for gid, c in gt_removed_centers.items():
        d = [np.linalg.norm(t.center[r][:2] - c[:2]) for r in rows]
        obj = int(rows[int(np.argmin(d))]) + 1
        assert min(d) < 0.5, f"ground-truth object {gid} is not in the map after lap 1"
        nondet, when = 0, None
        for e in smap.events:
            if e.session != 1 or e.object_id != obj:
                continue
            if e.kind == "non-detection":
                nondet += 1
            if e.kind == "removed":
                when = (e.frame, nondet)
                break
        out[gid] = (obj, when)
    return out


def test_higher_v_other_removes_gone_objects_after_fewer_non_detections(house, tmp_path):
    out, summary = house
    gone = summary["changes"][1]["removed"]
    assert len(gone) >= 2
    lap1_gt = {o["id"]: np.array(o["center"]) for o in json.loads((out / "lap1" / "ground_truth.json").read_text())["objects"]}
    # A high-recall calibration measured by ltc calibrate, and the calibration of a poor detector.
    high = tmp_path / "high.yaml"
    assert run("calibrate", out / "lap1", "-o", high).exit_code == 0
    v_high = yaml.safe_load(high.read_text())["v_other"]
    low = tmp_path / "low.yaml"
    low.write_text("format: ltc-calibration/1\ndetector: recorded\nv_other: 0.3\nrecall: 0.3\n")
    assert v_high > 0.6
    # The same lap-1 map for both, then lap 2 with each calibration.
    base = tmp_path / "lap1.h5"
    assert run("ingest", out / "lap1", "--map", base).exit_code == 0
    records = {}
    for name, cal in (("high", high), ("low", low)):
        m = tmp_path / f"{name}.h5"
        shutil.copyfile(base, m)
        # The detector's calibration alone: misses are the detector's word (not the depth's), each
        # one counting, with D capped at 5 and no removal at the session's end (absence), as when
        # v_Other was the only knob.
        r = run("ingest", out / "lap2", "--map", m, "--calibration", cal, "--set", "maintenance.seen_empty_share=null",
                "--set", "maintenance.nondet_min_move=null", "--set", "maintenance.nondet_min_turn=null",
                "--set", "integration.max_weight=5", "--set", "maintenance.absent_after_views=null")
        assert r.exit_code == 0, r.output
        assert load_map(m).sessions[1]["v_other"] == pytest.approx(v_high if name == "high" else 0.3)
        records[name] = removal_record(m, {g: lap1_gt[g] for g in gone})
    # when = (frame, non-detections in lap 2) of the removal, None = still in the map.
    sooner = 0
    for g in gone:
        obj_h, when_h = records["high"][g]
        obj_l, when_l = records["low"][g]
        assert obj_h == obj_l  # the same lap-1 map
        if when_h is None:  # not removed within the lap even with the higher v_other
            assert when_l is None, (g, when_l)
            continue
        if when_l is None:
            sooner += 1
        else:
            assert when_h[0] <= when_l[0] and when_h[1] <= when_l[1], (g, when_h, when_l)
            sooner += when_h[1] < when_l[1]
    assert sooner >= 2, records
    # (At this writing, v_other 0.80 removes the three after 3, 2 and 3 non-detections; 0.3 after 6
    # and 5, and never removes the third within the lap.)


def test_match_frame_with_large_ids():
    ids = np.zeros((H, W), np.int64)
    ids[0:10, 0:10] = 3_000_000
    ids[20:30, 0:10] = 70_000
    gt_ids, px, pairs = match_frame(ids, [rect(0, 10, 20, 30), rect(0, 10, 0, 10)], 0.5)
    assert gt_ids.tolist() == [70_000, 3_000_000] and px.tolist() == [100, 100]
    assert sorted(pairs) == [(0, 0, 1.0), (1, 1, 1.0)]


def test_a_calibration_replaces_the_learnt_detection_rate():
    """The default learns v_Other per class from the map; a calibration measured on annotated frames
    is the better estimate, so with one the learnt rate is off and its v_Other values are used."""
    from ltc_cli.config import defaults, settings_from
    from ltc_cli.tools.calibration_file import calibration_settings

    assert defaults()["maintenance"]["learn_detection_rate"] is True
    doc = {"v_other": 0.7, "per_class": {"chair": {"v_other": 0.6}, "tv": {"recall": 0.2}}}
    m = settings_from(defaults(), calibration_settings(doc))["maintenance"]
    assert (m["learn_detection_rate"], m["v_other"], m["v_other_per_class"]) == (False, 0.7, {"chair": 0.6})

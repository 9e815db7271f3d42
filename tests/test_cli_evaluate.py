"""ltc simulate -> ltc ingest (two sessions) -> ltc evaluate, through the command line."""

import json

import pytest
from click.testing import CliRunner

from ltc_cli.cli import cli
from ltc_cli.recordings.groundtruth import read_ground_truth


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


@pytest.fixture(scope="module")
def mapped(tmp_path_factory):
    out = tmp_path_factory.mktemp("sim") / "house"
    r = run("simulate", out, "--scene", "tiny", "--seed", "3", "--width", "320", "--height", "240")
    assert r.exit_code == 0, r.output
    assert r.output.strip().endswith("MB") and "2 laps of the tiny house (seed 3)" in r.output
    m = out.parent / "map.h5"
    for lap in ("lap1", "lap2"):
        r = run("ingest", out / lap, "--map", m)
        assert r.exit_code == 0, r.output
    return out, m


def test_evaluate_table_and_json(mapped):
    out, m = mapped
    r = run("evaluate", m, "--ground-truth", out / "lap2")
    assert r.exit_code == 0, r.output
    lines = r.output.splitlines()
    assert lines[0].split()[:3] == ["TP", "FP", "FN"]
    assert any(ln.startswith("all ") for ln in lines)
    assert lines[-1].startswith(f"{m}: precision")
    r = CliRunner().invoke(cli, ["evaluate", str(m), "--ground-truth", str(out / "lap2"), "--format", "json"])
    doc = json.loads(r.stdout)
    gt = read_ground_truth(out / "lap2")
    assert doc["tp"] + doc["fn"] + doc["ignored_gt"] == len(gt["objects"])
    assert doc["tp"] + doc["fp"] == doc["num_map"]
    for k in ("precision", "recall", "recall_seen", "f1"):
        assert 0 <= doc[k] <= 1
    # lap2's changes and lap1's boxes (found beside it) were used to look for ghosts.
    assert doc["ghosts"] == len(doc["ghost_ids"]) and doc["duplicates"] == len(doc["duplicate_ids"])


def test_evaluate_bad_ground_truth_is_one_line(mapped, tmp_path):
    out, m = mapped
    bad = tmp_path / "gt.json"
    bad.write_text('{"objects": [{"id": 1}]}')
    r = CliRunner().invoke(cli, ["evaluate", str(m), "--ground-truth", str(bad)])
    assert r.exit_code == 1
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and str(bad) in lines[0] and "objects.0" in lines[0]


def test_simulate_bad_option_is_one_line(tmp_path):
    r = CliRunner().invoke(cli, ["simulate", str(tmp_path / "x"), "--set", "no_such_option=1"])
    assert r.exit_code == 1
    assert len([ln for ln in r.stderr.splitlines() if ln.strip()]) == 1 and "no_such_option" in r.stderr


def test_evaluate_reports_iou_levels_and_multi_lap_figures(mapped):
    out, m = mapped
    r = CliRunner().invoke(cli, ["evaluate", str(m), "--ground-truth", str(out / "lap2"), "--format", "json"])
    doc = json.loads(r.stdout)
    assert doc["iou_measure"] == "xy_iou" and doc["earlier_laps"] == 1
    # Matches at a threshold are the any-overlap matches above it.
    for t in ("0.25", "0.5"):
        assert doc["at_iou"][t]["tp"] == sum(1 for x in doc["matches"] if x["xy_iou"] > float(t))
    d = doc["deleted_while_present"]
    assert d["present"] == doc["num_gt"] and d["count"] == len(d["gt_ids"])
    r = run("evaluate", m, "--ground-truth", out / "lap2")
    rows = {ln[:14].strip(): ln[14:].split() for ln in r.output.splitlines()}
    assert rows["XY IoU > 0.25"][0] == str(doc["at_iou"]["0.25"]["tp"])
    assert rows["XY IoU > 0.5"][0] == str(doc["at_iou"]["0.5"]["tp"])
    assert "at XY IoU > 0.25: precision" in r.output.splitlines()[-1]
    deleted = next(ln for ln in r.output.splitlines() if ln.startswith("maintenance deleted"))
    assert (f"on {d['count']} of the {d['present']} objects" in deleted
            and f"{len(d['duplicates_removed'])} second box(es) removed" in deleted)


def _write_laps(root):
    """Three laps' ground truth (plant 2 removed in lap 2) and a map with the plant still in it."""
    from ltc_cli.map.model import SemanticMap
    from ltc_cli.map.store import save_map
    from tests.sample_maps import add

    def obj(i, c, x):
        return {"id": i, "class": c, "center": [x, 0, 0.5], "yaw": 0.0, "size": [1, 1, 1], "seen_pixels": 900}

    laps = [[obj(1, "chair", 0), obj(2, "potted plant", 4)], [obj(1, "chair", 0)], [obj(1, "chair", 0)]]
    for k, objs in enumerate(laps, start=1):
        (root / f"lap{k}").mkdir()
        (root / f"lap{k}" / "ground_truth.json").write_text(json.dumps({"lap": k, "objects": objs}))
    smap = SemanticMap.new(["chair", "potted plant"])
    add(smap, [0, 0, 0.5], 0.0, [1, 1, 1], "chair", 0.8)
    add(smap, [4, 0.1, 0.5], 0.0, [1, 1, 1], "potted plant", 0.8)
    save_map(smap, root / "map.h5")
    return root / "map.h5"


def test_evaluate_finds_every_earlier_lap(tmp_path):
    m = _write_laps(tmp_path)
    args = ["evaluate", str(m), "--ground-truth", str(tmp_path / "lap3"), "--format", "json"]
    doc = json.loads(CliRunner().invoke(cli, args).stdout)
    assert (doc["ghosts"], doc["ghost_ids"], doc["earlier_laps"]) == (1, [2], 2)
    # --previous replaces the search; repeated, it gives several laps.
    doc = json.loads(CliRunner().invoke(cli, args + ["--previous", str(tmp_path / "lap2")]).stdout)
    assert (doc["ghosts"], doc["earlier_laps"]) == (0, 1)
    doc = json.loads(CliRunner().invoke(
        cli, args + ["--previous", str(tmp_path / "lap1"), "--previous", str(tmp_path / "lap2")]).stdout)
    assert (doc["ghosts"], doc["earlier_laps"]) == (1, 2)
    r = run("evaluate", m, "--ground-truth", tmp_path / "lap3")
    assert r.exit_code == 0 and "1 ghosts" in r.output.splitlines()[-1]


def test_evaluate_empty_map_prints_na_not_zero(tmp_path):
    from ltc_cli.map.model import SemanticMap
    from ltc_cli.map.store import save_map

    m = tmp_path / "empty.h5"
    save_map(SemanticMap.new(["chair"]), m)
    gt = tmp_path / "gt.json"
    gt.write_text(json.dumps({"objects": [{"id": 1, "class": "chair", "center": [0, 0, 0.5], "yaw": 0,
                                           "size": [1, 1, 1]}]}))
    r = CliRunner().invoke(cli, ["evaluate", str(m), "--ground-truth", str(gt), "--format", "json"])
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    assert doc["precision"] is None and doc["recall"] == 0.0 and doc["at_iou"]["0.5"]["precision"] is None
    assert '"precision": null' in r.stdout
    r = run("evaluate", m, "--ground-truth", gt)
    all_row = next(ln for ln in r.output.splitlines() if ln.startswith("all "))
    assert all_row.split()[1:6] == ["0", "0", "1", "n/a", "0.000"]
    assert "precision n/a" in r.output.splitlines()[-1] and "0.000 precision" not in r.output

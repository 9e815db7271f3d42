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

"""ltc query: every filter on a hand-built map, the three output forms, errors, and a 100k-object map."""

import csv
import io
import json
import time

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from ltc_cli.cli import cli
from ltc_cli.map.model import ACTIVE
from ltc_cli.map.query import Query, QueryError, classify, records, select
from ltc_cli.map.store import load_map, save_map
from tests.sample_maps import big_map, hand_map


def ids(smap, **kw):
    return select(smap, Query(**kw)).rows.__add__(1).tolist()


@pytest.fixture(scope="module")
def smap():
    return hand_map()


@pytest.fixture(scope="module")
def map_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("q") / "hand.h5"
    save_map(hand_map(), path)
    return path


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def test_no_filter_lists_the_active_objects(smap):
    res = select(smap, Query())
    assert (res.rows + 1).tolist() == [1, 2, 3, 4, 5]
    assert res.total == 5 and res.distance is None


def test_class_filter_one_and_several(smap):
    assert ids(smap, classes=["chair"]) == [1, 2]  # 6 is removed, 8 merged: neither shows
    assert ids(smap, classes=["chair", "tv"]) == [1, 2, 4]
    assert ids(smap, classes=["table"]) == [3, 5]


def test_class_is_the_argmax_without_other():
    """An object whose `other` score is the largest still has a class: the best of the rest."""
    from tests.sample_maps import add
    from ltc_cli.map.model import SemanticMap

    m = SemanticMap.new(["a", "b"])
    add(m, [0, 0, 0], 0.0, [1, 1, 1], "a", 0.5)
    m.objects.cols["scores"][0] = [0.1, 0.3, 0.6]
    cls, conf = classify(m)
    assert cls.tolist() == [1] and conf.tolist() == [0.3]


def test_near_2d_and_3d(smap):
    # tv 4 is 1 m from (1, 0) in XY but 2.5 m up: in the 2-D query, not in the 3-D one.
    res = select(smap, Query(near=[1, 0], radius=1.0))
    assert (res.rows + 1).tolist() == [1, 4]
    np.testing.assert_allclose(res.distance, [0.0, 1.0])
    res3 = select(smap, Query(near=[1, 0, 0.45], radius=1.0))
    assert (res3.rows + 1).tolist() == [1]
    assert ids(smap, near=[1, 0, 0.45], radius=2.3) == [1, 2, 3, 4]  # 4 at sqrt(1 + 2.05^2) = 2.28
    assert ids(smap, near=[10, 10], radius=0.0) == [5]  # inclusive


def test_min_confidence_and_id(smap):
    assert ids(smap, min_confidence=0.7) == [1, 3, 4]  # 0.8, 0.9, 0.7 (inclusive)
    assert ids(smap, min_confidence=0.95) == []
    assert ids(smap, ids=[2, 5]) == [2, 5]
    assert ids(smap, ids=[6, 8]) == []  # removed and merged objects are not active
    assert ids(smap, classes=["chair"], min_confidence=0.6, near=[0, 0], radius=5) == [1]


def test_removed_objects_with_when_and_why(smap):
    res = select(smap, Query(removed=True))
    assert (res.rows + 1).tolist() == [6, 7] and res.total == 2
    recs = records(smap, res)
    assert recs[0]["removed"] == {"session": 1, "frame": 7, "frame_key": "lap2/000007",
                                  "detail": "other 0.520 > chair 0.400 after 4 non-detections and 3 detections"}
    assert recs[1]["removed"]["frame_key"] == "lap2/000012" and recs[1]["class"] == "tv"
    assert ids(smap, removed=True, classes=["tv"]) == [7]
    assert ids(smap, removed=True, ids=[1, 6]) == [6]


def test_records_carry_every_field(smap):
    rec = records(smap, select(smap, Query(ids=[3], near=[0, 0], radius=9)))[0]
    assert rec["id"] == 3 and rec["class"] == "table" and rec["confidence"] == 0.9
    assert rec["center"] == [0, 2, 0.4] and rec["yaw"] == -0.2 and rec["size"] == [1.6, 0.9, 0.8]
    assert rec["defined"] is True and rec["n_det"] == 3 and rec["n_nondet"] == 0
    assert rec["first_seen"] == {"session": 0, "frame": 1} and rec["last_seen"] == {"session": 0, "frame": 9}
    assert rec["distance"] == 2.0


def test_unknown_class_is_an_error_naming_the_map(smap):
    with pytest.raises(QueryError, match=r"m\.h5: unknown class 'sofa'.*chair, table, tv"):
        select(smap, Query(classes=["sofa"]), "m.h5")


# -- the command line ----------------------------------------------------------------------------

def test_cli_table(map_file):
    r = run("query", map_file, "--class", "chair", "--class", "tv")
    assert r.exit_code == 0, r.output
    lines = r.stdout.splitlines()
    assert lines[0].split()[:3] == ["id", "class", "conf"]
    assert [ln.split()[0] for ln in lines[1:]] == ["1", "2", "4"]
    assert [ln.split()[1] for ln in lines[1:]] == ["chair", "chair", "tv"]
    # Aligned: every column starts at the same offset on every line.
    assert len({ln.index(ln.split()[2]) + len(ln.split()[2]) for ln in lines}) == 1
    assert r.stderr.strip() == f"{map_file}: 3 of 5 objects"


def test_cli_json(map_file):
    r = run("query", map_file, "--near", "1,0", "--radius", "1", "--format", "json")
    assert r.exit_code == 0, r.output
    recs = json.loads(r.stdout)
    assert [(x["id"], x["distance"]) for x in recs] == [(1, 0.0), (4, 1.0)]
    assert r.stderr.strip() == f"{map_file}: 2 of 5 objects"


def test_cli_csv_removed(map_file):
    r = run("query", map_file, "--removed", "--format", "csv")
    assert r.exit_code == 0, r.output
    rows = list(csv.DictReader(io.StringIO(r.stdout)))
    assert [row["id"] for row in rows] == ["6", "7"]
    assert rows[0]["removed_frame_key"] == "lap2/000007" and rows[0]["removed_session"] == "1"
    assert rows[1]["removed_detail"].startswith("other 0.510 > tv 0.450")
    assert r.stderr.strip() == f"{map_file}: 2 of 2 removed objects"


def test_cli_table_removed_shows_why(map_file):
    r = run("query", map_file, "--removed", "--id", "7")
    assert r.exit_code == 0
    assert "lap2/000012" in r.stdout and "other 0.510 > tv 0.450" in r.stdout


def test_cli_negative_point_and_3d(map_file):
    r = run("query", map_file, "--near", "-1,0,0.45", "--radius", "2.01", "--format", "json")
    assert r.exit_code == 0, r.output
    assert [x["id"] for x in json.loads(r.stdout)] == [1]


def test_cli_nothing_matches(map_file):
    r = run("query", map_file, "--min-confidence", "0.99")
    assert r.exit_code == 0 and r.stdout == "" and r.stderr.strip() == f"{map_file}: 0 of 5 objects"


@pytest.mark.parametrize("cmd", [["query"], ["export", "--format", "json"], ["export", "--format", "geojson"],
                                 ["render", "-o", "OUT"]])
def test_cli_bad_map_one_line_exit_1(tmp_path, cmd):
    """Missing file, junk file, an HDF5 file that is not a map: one line naming the file, exit 1."""
    junk = tmp_path / "junk.h5"
    junk.write_bytes(b"not hdf5 at all")
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f["x"] = 1
    cmd = [str(tmp_path / "out.png") if c == "OUT" else c for c in cmd]
    for path, why in ((tmp_path / "missing.h5", "does not exist"), (junk, "not an ltc map"), (other, "not an ltc map")):
        r = CliRunner().invoke(cli, [cmd[0], str(path), *cmd[1:]])
        assert r.exit_code == 1, (cmd, r.output)
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and str(path) in lines[0] and why in lines[0], lines
        assert "Traceback" not in r.output and r.stdout == ""
    assert not (tmp_path / "out.png").exists()


def test_cli_usage_errors_exit_2(map_file):
    assert run("query", map_file, "--near", "1,2").exit_code == 2  # no radius
    assert run("query", map_file, "--radius", "1").exit_code == 2  # no point
    assert run("query", map_file, "--near", "1", "--radius", "1").exit_code == 2
    assert run("query", map_file, "--near", "a,b", "--radius", "1").exit_code == 2
    assert run("query", map_file, "--radius", "-1", "--near", "0,0").exit_code == 2
    assert run("query", map_file, "--min-confidence", "1.5").exit_code == 2
    r = run("query", map_file, "--class", "sofa")
    assert r.exit_code == 1 and "unknown class 'sofa'" in r.stderr and str(map_file) in r.stderr


def test_100k_objects_vectorised(tmp_path, capsys):
    """Filters on 100,000 objects agree with a plain per-row check; prints the time (no assert)."""
    smap = big_map(100_000)
    path = tmp_path / "big.h5"
    save_map(smap, path)
    t0 = time.perf_counter()
    smap = load_map(path)
    t1 = time.perf_counter()
    q = Query(classes=["class03", "class07"], near=[10.0, -20.0], radius=30.0, min_confidence=0.15)
    res = select(smap, q)
    t2 = time.perf_counter()
    recs = records(smap, res)
    t3 = time.perf_counter()
    all_rows = select(smap, Query())
    recs_all = records(smap, all_rows)
    t4 = time.perf_counter()

    t = smap.objects
    cls, conf = classify(smap)
    expect = [r + 1 for r in range(t.n)
              if t.status[r] == ACTIVE and cls[r] in (3, 7) and conf[r] >= 0.15
              and np.hypot(t.center[r, 0] - 10.0, t.center[r, 1] + 20.0) <= 30.0]
    assert [x["id"] for x in recs] == expect and len(expect) > 50
    assert len(recs_all) == int((t.status == ACTIVE).sum())
    with capsys.disabled():
        print(f"\n[query 100k] load_map {t1 - t0:.3f} s; filter {1e3 * (t2 - t1):.1f} ms -> {len(recs)} rows, "
              f"records {1e3 * (t3 - t2):.1f} ms; all {len(recs_all)} active as records {t4 - t3:.3f} s")

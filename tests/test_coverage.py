"""Where a session looked (ltc_cli/map/coverage.py): cells by hand, the text form, a frame's seen cells
from a camera looking down at a floor, a box's footprint cells; ``ltc changes`` counting an addition
at a place no earlier session looked at as first seen, not added; and an ingest keeping the cells
in its session row, a resumed run to the bit."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from ltc_cli.cli import cli
from ltc_cli.config import defaults
from ltc_cli.ingest.session import ingest
from ltc_cli.map.changes import map_changes
from ltc_cli.map.coverage import (Coverage, cell_keys, decode, encode, footprint_cells, key_cells, seen_cells)
from ltc_cli.map.model import SemanticMap
from ltc_cli.map.store import load_map, save_map
from ltc_cli.types import Intrinsics
from tests.sample_maps import SESSION, add

LAP1 = Path(__file__).resolve().parent.parent / "sample_data" / "lap1"


def pairs(keys) -> list:
    """The cells (ix, iy) of ``keys``, sorted."""
    return sorted(map(tuple, key_cells(keys).tolist()))


def cells(*ij) -> np.ndarray:
    return cell_keys((np.array(ij, dtype=float) + 0.5) * 0.25)  # the middle of each cell (i, j)


def test_cells_by_hand():
    keys = cell_keys(np.array([[0.1, -0.1], [-0.3, 0.6], [0.24, -0.01], [-0.3, 0.74]]))
    assert pairs(keys) == [(-2, 2), (0, -1)]
    big = np.array([[-1e5, 3e4], [2.5e5, -7e5]])
    assert pairs(cell_keys(big)) == [(-400000, 120000), (1000000, -2800000)]


def test_text_round_trip_and_refusals():
    keys = cell_keys(np.random.default_rng(3).uniform(-40, 40, (500, 2)))
    got, cell = decode(encode(keys))
    np.testing.assert_array_equal(got, keys)
    assert cell == 0.25 and encode(keys).startswith("0.25:")
    assert decode(encode(np.zeros(0, np.int64), 0.5))[1] == 0.5 and decode(encode(np.zeros(0, np.int64)))[0].size == 0
    for bad in ("", "0.25", "x:eJw=", "-1:eJwDAAAAAAE=", "0.25:not base64!", "0.25:" + "AAAA"):
        with pytest.raises(ValueError):
            decode(bad)
    assert Coverage.resumed("garbage").keys == set() and Coverage.resumed("").text().startswith("0.25:")
    # A session an older ltc began (frames mapped, no cells kept) stays unknown when resumed.
    older = Coverage.resumed("", frames_done=12)
    older.add(np.ones((80, 80)), looking_down(), Intrinsics(80, 80, 100.0, 100.0, 39.5, 39.5), (0.3, 6.0))
    assert older.text() == "" and older.keys == set()


def looking_down(height: float = 1.0) -> np.ndarray:
    """T_map_camera (4, 4): the camera at (0, 0, height), its z axis down, its x along the map's x."""
    T = np.eye(4)
    T[:3, :3] = np.diag([1.0, -1.0, -1.0])
    T[2, 3] = height
    return T


def test_a_view_of_the_floor_sees_the_cells_under_it():
    # 80 x 80 px, f 100, the centre at 39.5: one reading a block of 8, stage 4's, at u = 3, 11, ..., 75,
    # so the floor 1 m below is seen from x = (3 - 39.5) / 100 = -0.365 to (75 - 39.5) / 100 = 0.355:
    # cells -2..1 on each axis (y = -(v - 39.5) / 100, from 0.365 to -0.355).
    intr = Intrinsics(80, 80, 100.0, 100.0, 39.5, 39.5)
    depth = np.ones((80, 80))
    got = pairs(seen_cells(depth, looking_down(), intr, (0.3, 6.0)))
    assert got == [(i, j) for i in range(-2, 2) for j in range(-2, 2)]
    # Readings out of range (none, or beyond 6 m) see nothing: the right half at 7 m leaves u <= 35.
    depth[:, 40:] = 7.0
    depth[:16, :] = 0.0
    got = pairs(seen_cells(depth, looking_down(), intr, (0.3, 6.0)))
    assert got == [(i, j) for i in (-2, -1) for j in range(-2, 1)]  # v >= 19: y <= 0.205


def test_a_footprints_cells_by_hand():
    # 0.5 x 0.5 m at (0.125, 0.125): x and y from -0.125 to 0.375, cells -1..1 each way.
    got = pairs(footprint_cells(np.array([0.125, 0.125, 0.4]), 0.0, np.array([0.5, 0.5, 0.8])))
    assert got == [(i, j) for i in (-1, 0, 1) for j in (-1, 0, 1)]
    # Turned 90 degrees, a 1.0 x 0.1 m box at (2.1, 0.05) spans y -0.45..0.55 and x 2.05..2.15.
    got = pairs(footprint_cells(np.array([2.1, 0.05, 0.4]), np.pi / 2, np.array([1.0, 0.1, 0.8])))
    assert got == [(8, j) for j in range(-2, 3)]


def two_sessions(coverage0: str | None) -> SemanticMap:
    """Session 0 saw the cells (0..3, 0..3) (x and y 0 to 1 m); session 1 added a chair there, a
    chair half over the edge of what session 0 saw, and a tv 5 m away."""
    m = SemanticMap.new(["chair", "tv"])
    m.sessions = [dict(SESSION), dict(SESSION)]
    if coverage0 is not None:
        m.sessions[0]["coverage"] = coverage0
    m.sessions[1]["coverage"] = encode(cells(*[(i, j) for i in range(30) for j in range(30)]))
    add(m, [0.5, 0.5, 0.45], 0.0, [0.5, 0.5, 0.9], "chair", 0.8, seen=(1, 1, 1, 9))
    add(m, [0.75, 0.5, 0.45], 0.0, [0.5, 0.5, 0.9], "chair", 0.8, seen=(1, 1, 1, 9))  # x 0.5..1.0: 2 of 3 columns seen
    add(m, [1.3, 0.5, 0.45], 0.0, [0.5, 0.5, 0.9], "chair", 0.8, seen=(1, 1, 1, 9))  # x 1.05..1.55: none seen
    add(m, [5.5, 5.5, 1.0], 0.0, [0.6, 0.1, 0.4], "tv", 0.8, seen=(1, 1, 1, 9))
    return m


def test_an_addition_where_no_earlier_session_looked_is_first_seen_not_added():
    seen0 = encode(cells(*[(i, j) for i in range(4) for j in range(4)]))
    report = map_changes(two_sessions(seen0), since=0)
    assert sorted(c.object_id for c in report.changes if c.kind == "added") == [1, 2]
    assert report.first_seen == 2
    # A map whose earlier sessions kept no cells (written before) reports every addition.
    report = map_changes(two_sessions(None), since=0)
    assert (report.count("added"), report.first_seen) == (4, 0)
    assert map_changes(two_sessions(seen0), since=-1).count("added") == 4  # against an empty map


def test_changes_cli_says_how_many_were_first_seen(tmp_path):
    m = tmp_path / "m.h5"
    save_map(two_sessions(encode(cells(*[(i, j) for i in range(4) for j in range(4)]))), m)
    r = CliRunner().invoke(cli, ["changes", str(m), "--format", "json"])
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    assert doc["first_seen"] == 2 and [c["id"] for c in doc["changes"]] == [1, 2]
    assert "2 objects first seen where no earlier session looked" in r.stderr


def test_an_ingest_keeps_the_cells_it_saw_and_a_resumed_run_the_same(tmp_path):
    whole = tmp_path / "whole.h5"
    ingest([LAP1], whole, defaults())
    smap = load_map(whole)
    seen, cell = decode(smap.sessions[0]["coverage"])
    assert cell == 0.25 and len(seen) > 50
    # Every object the session mapped stands where it looked.
    keys = set(seen.tolist())
    for r in smap.active_rows():
        under = footprint_cells(smap.objects.center[r], smap.objects.yaw[r], smap.objects.size[r])
        assert set(under.tolist()) & keys, r
    m, asked = tmp_path / "m.h5", []
    s = ingest([LAP1], m, defaults(), checkpoint_every=5, should_stop=lambda: asked.append(1) or len(asked) > 23)
    assert s.interrupted
    part = decode(load_map(m).sessions[0]["coverage"])[0]
    assert 0 < len(part) < len(seen)
    ingest([LAP1], m, defaults())
    assert load_map(m).sessions[0]["coverage"] == smap.sessions[0]["coverage"]


def test_info_says_how_much_floor_plan_each_session_saw(tmp_path):
    m = tmp_path / "m.h5"
    ingest([LAP1], m, defaults(), frames=slice(0, 30))
    r = CliRunner().invoke(cli, ["info", str(m), "--format", "json"])
    assert r.exit_code == 0, r.output
    n = len(decode(load_map(m).sessions[0]["coverage"])[0])
    assert json.loads(r.stdout)["sessions"][0]["seen_m2"] == n * 0.25 * 0.25 > 0
    r = CliRunner().invoke(cli, ["info", str(m)])
    assert f"saw {n * 0.0625:.1f} m2 of floor plan" in r.output
    save_map(two_sessions(None), m)  # sessions that kept none: no line, and null
    r = CliRunner().invoke(cli, ["info", str(m), "--format", "json"])
    assert [s["seen_m2"] for s in json.loads(r.stdout)["sessions"]] == [None, 900 * 0.0625]


def test_render_shades_the_floor_plan_seen(tmp_path):
    from matplotlib.colors import to_rgb
    from PIL import Image

    from ltc_cli.map.coverage import sessions_seen
    from ltc_cli.map.render import render_map
    from ltc_cli.map.render_marks import SEEN_COLOUR

    smap = two_sessions(encode(cells(*[(i, j) for i in range(4) for j in range(4)])))
    # Session 0 saw x and y 0..1 m; with session 1, 0..7.5 m: (3.1, 6.1), off the grid lines, by both only.
    for rows, want in ((smap.sessions[:1], False), (smap.sessions, True)):
        res = render_map(smap, tmp_path / "m.png", seen=sessions_seen(rows), labels=False)
        img = np.asarray(Image.open(tmp_path / "m.png").convert("RGB")).astype(int)
        shade = np.round(np.array(to_rgb(SEEN_COLOUR)) * 255).astype(int)
        for (x, y), seen in (((0.1, 0.9), True), ((3.1, 6.1), want)):
            c, r, _ = res.world_to_pixel @ [x, y, 1.0]
            got = img[int(r), int(c)]
            assert (np.abs(got - shade).max() <= 2) == seen, (x, y, got)
    m = tmp_path / "m.h5"
    save_map(smap, m)
    r = CliRunner().invoke(cli, ["render", str(m), "-o", str(tmp_path / "c.png"), "--coverage"])
    assert r.exit_code == 0 and "56.2 m2 seen" in r.output, r.output  # 900 cells of 0.0625 m2
    save_map(two_sessions(None), m)
    r = CliRunner().invoke(cli, ["render", str(m), "-o", str(tmp_path / "d.png"), "--coverage", "--changes"])
    assert r.exit_code == 1 and "kept no record of where they looked" in r.output and "Traceback" not in r.output
    r = CliRunner().invoke(cli, ["render", str(m), "-o", str(tmp_path / "e.png"), "--coverage", "--recording", "x"])
    assert r.exit_code == 2 and "--coverage draws the top-down picture" in r.output

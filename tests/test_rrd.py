"""ltc export --format rrd and ltc view --save: the .rrd file holds the map's boxes (read back with
rerun's own reader) and, with a recording, the camera on a timeline. Skipped when the optional extra
ltc[viz] (rerun-sdk) is absent; without it the commands say how to get it in one line."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from ltc_cli.cli import cli
from ltc_cli.map.model import REMOVED
from ltc_cli.map.store import save_map
from tests.sample_maps import hand_map

SAMPLE = Path(__file__).resolve().parents[1] / "sample_data"


def test_missing_extra_is_one_clear_line(tmp_path, monkeypatch):
    save_map(hand_map(), tmp_path / "m.h5")
    monkeypatch.setitem(sys.modules, "rerun", None)  # as if rerun-sdk were not installed
    for args in (["export", str(tmp_path / "m.h5"), "--format", "rrd", "-o", str(tmp_path / "m.rrd")],
                 ["view", str(tmp_path / "m.h5")]):
        r = CliRunner().invoke(cli, args)
        assert r.exit_code == 1
        assert r.output.strip() == "Error: rerun-sdk is not installed: pip install 'ltc[viz]' (or pip install rerun-sdk)"
    assert not (tmp_path / "m.rrd").exists()


def columns(path, entity):
    """{column: first row's values} of the chunks of one entity in an .rrd file."""
    from rerun.chunk import RrdReader

    out = {}
    for chunk in RrdReader(str(path)).stream():
        if chunk.entity_path == entity:
            batch = chunk.to_record_batch()
            for name in batch.schema.names:
                if not name.startswith("rerun.") and "time" not in name:
                    out.setdefault(name, []).extend(batch.column(name).to_pylist())
    return out


def test_rrd_holds_the_boxes(tmp_path):
    pytest.importorskip("rerun.chunk", reason="the optional extra ltc[viz] (rerun-sdk) is not installed")
    smap = hand_map()
    save_map(smap, tmp_path / "m.h5")
    r = CliRunner().invoke(cli, ["export", str(tmp_path / "m.h5"), "--format", "rrd", "-o", str(tmp_path / "m.rrd")])
    assert r.exit_code == 0, r.output
    cols = columns(tmp_path / "m.rrd", "/world/objects")
    t, rows = smap.objects, smap.active_rows()
    np.testing.assert_allclose(cols["Boxes3D:centers"][0], t.center[rows], atol=1e-6)
    np.testing.assert_allclose(cols["Boxes3D:half_sizes"][0], t.size[rows] / 2, atol=1e-6)
    angles = cols["Boxes3D:rotation_axis_angles"][0]
    assert all(a["axis"] == [0.0, 0.0, 1.0] for a in angles)
    np.testing.assert_allclose([a["angle"] for a in angles], t.yaw[rows], atol=1e-6)
    classes = [smap.classes[int(i)] for i in t.scores[rows, :-1].argmax(axis=1)]
    assert cols["Boxes3D:class_ids"][0] == [smap.classes.index(c) for c in classes]
    assert [lb.split(" (")[0] for lb in cols["Boxes3D:labels"][0]] == [f"{c} #{r + 1}" for c, r in zip(classes, rows)]
    gone = columns(tmp_path / "m.rrd", "/world/removed")
    assert len(gone["Boxes3D:centers"][0]) == int((t.status == REMOVED).sum()) == 2
    assert "removed in session 1" in gone["Boxes3D:labels"][0][0]


def test_view_saves_the_camera_path_and_images(tmp_path):
    pytest.importorskip("rerun.chunk", reason="the optional extra ltc[viz] (rerun-sdk) is not installed")
    m = tmp_path / "m.h5"
    r = CliRunner().invoke(cli, ["ingest", str(SAMPLE / "lap1"), "--map", str(m)])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(cli, ["view", str(m), str(SAMPLE / "lap1"), "--every", "10", "--save", str(tmp_path / "v.rrd")])
    assert r.exit_code == 0, r.output
    assert "8 frames" in r.output  # 76 frames, every 10th: 0, 10, ..., 70
    cam = columns(tmp_path / "v.rrd", "/world/camera")
    poses = [ln.split() for ln in (SAMPLE / "lap1" / "poses.txt").read_text().splitlines() if ln.strip()]
    # The sample world is z-up: the map frame is the recording's world; frame 10's camera position.
    np.testing.assert_allclose(cam["Transform3D:translation"][1], [np.array(poses[10][1:4], dtype=float)], atol=1e-5)
    assert len(columns(tmp_path / "v.rrd", "/world/camera/rgb")) > 0
    path = columns(tmp_path / "v.rrd", "/world/camera_path")
    assert len(path["LineStrips3D:strips"][0][0]) == 8


def test_view_counts_the_frames_it_could_not_read(tmp_path):
    # Frames 10 and 20 of the every-10th walk have no depth image: each gets its warning line, the
    # other six are logged, and the summary counts the two by reason, as ingest's does.
    pytest.importorskip("rerun.chunk", reason="the optional extra ltc[viz] (rerun-sdk) is not installed")
    import shutil

    rec = tmp_path / "lap1"
    shutil.copytree(SAMPLE / "lap1", rec)
    for key in ("000010", "000020"):
        (rec / "depth" / f"{key}.png").unlink()
    m = tmp_path / "m.h5"
    assert CliRunner().invoke(cli, ["ingest", str(SAMPLE / "lap1"), "--map", str(m)]).exit_code == 0
    out = tmp_path / "v.rrd"
    r = CliRunner().invoke(cli, ["view", str(m), str(rec), "--every", "10", "--save", str(out)])
    assert r.exit_code == 0, r.output
    lines = r.output.splitlines()
    for key in ("000010", "000020"):
        assert f"warning: skipped frame {key}: {rec / 'depth' / (key + '.png')}: image file is missing" in lines
    assert lines[-1] == f"{out}: 18 objects, 6 frames (2 skipped: 2 image file is missing) (open it with: rerun {out})"
    assert len(columns(out, "/world/camera_path")["LineStrips3D:strips"][0][0]) == 6

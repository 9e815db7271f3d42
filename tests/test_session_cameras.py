"""Each session row records the camera its recordings were read with (size, fx fy cx cy, and the
reader's calibration name), and ``ltc info`` shows it: a TUM folder without ``freiburgN`` in its
name is read with ROS's default camera, which a user should be able to see in the map."""

import json
from pathlib import Path

import h5py
import jsonschema
import yaml
from click.testing import CliRunner

from ltc_cli.cli import cli
from ltc_cli.ingest.session_row import camera_record
from ltc_plugins.readers import TumReader
from tests.test_readers import make_tum

LAP1 = Path(__file__).resolve().parent.parent / "sample_data" / "lap1"


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args], catch_exceptions=False)


def test_camera_record_names_the_tum_calibration(tmp_path):
    # The TUM page's values: ROS default 525 525 319.5 239.5; fr1 517.3 516.5 318.6 255.3.
    d = make_tum(tmp_path, name="tiny")
    rec = TumReader().open(d)
    size = {"width": rec.intrinsics.width, "height": rec.intrinsics.height}
    assert camera_record(rec) == size | {"fx": 525.0, "fy": 525.0, "cx": 319.5, "cy": 239.5, "camera": "ros"}
    rec = TumReader().open(d, {"camera": "fr1"})
    assert camera_record(rec) == size | {"fx": 517.3, "fy": 516.5, "cx": 318.6, "cy": 255.3, "camera": "fr1"}
    rec = TumReader().open(d, {"intrinsics": [500, 501, 320, 240]})
    assert camera_record(rec) == size | {"fx": 500.0, "fy": 501.0, "cx": 320.0, "cy": 240.0, "camera": "custom"}


def test_info_shows_each_sessions_camera(tmp_path):
    cam = yaml.safe_load((LAP1 / "recording.yaml").read_text())["camera"]
    m = tmp_path / "map.h5"
    assert run("ingest", LAP1, "--map", m).exit_code == 0
    out = run("info", m).output
    line = f"camera {cam['width']} x {cam['height']}, fx {cam['fx']:g} fy {cam['fy']:g} cx {cam['cx']:g} cy {cam['cy']:g}"
    assert line == "camera 320 x 240, fx 262.5 fy 262.5 cx 159.5 cy 119.5"
    doc = json.loads(run("info", m, "--format", "json").output)
    [recorded] = doc["sessions"][0]["cameras"]
    # The depth error measured on the frames (the simulated sensor's is 0.005 Z^2, smooth over
    # 8 x 8 pixel blocks, which a 32 pixel patch's plane partly absorbs).
    noise = recorded.pop("depth_noise")
    assert 0.0035 < noise < 0.0055
    assert recorded == cam
    shown = [ln.strip() for ln in out.splitlines() if ln.strip().startswith("camera ")]
    assert shown == [f"{line}, depth noise {noise:.2g} m at 1 m (measured)"]  # and no calibration name
    out = tmp_path / "map.json"  # the JSON export carries it too, and its schema holds
    assert run("export", m, "--format", "json", "-o", out).exit_code == 0
    exported = json.loads(out.read_text())
    assert exported["map"]["sessions"][0]["cameras"] == [cam | {"depth_noise": noise}]
    schema = json.loads((Path(__file__).resolve().parent.parent / "schemas" / "export.schema.json").read_text())
    jsonschema.validate(exported, schema)


def test_maps_without_cameras_still_read_and_grow(tmp_path):
    m = tmp_path / "map.h5"
    assert run("ingest", LAP1, "--map", m).exit_code == 0
    with h5py.File(m, "a") as f:  # a map written before sessions recorded their camera
        del f["sessions/cameras"]
    r = run("info", m)
    assert r.exit_code == 0 and not [ln for ln in r.output.splitlines() if ln.strip().startswith("camera ")]
    assert run("ingest", LAP1, "--map", m, "--revisit").exit_code == 0
    doc = json.loads(run("info", m, "--format", "json").output)
    assert [len(s["cameras"]) for s in doc["sessions"]] == [0, 1]
    assert doc["sessions"][1]["cameras"][0]["fx"] == 262.5

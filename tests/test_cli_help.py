"""Words users read instead of the source: every simulator option named in `ltc simulate --help`
with its default, progress while simulating, singulars for one, query columns in words, and
local-metre GeoJSON that says it is not longitude/latitude."""

from __future__ import annotations

from click.testing import CliRunner

from ltc_cli.cli import cli
from ltc_cli.cli_tools import SIMULATE_OPTIONS_HELP
from ltc_cli.tools.simulate import DEFAULTS, simulate


def test_simulate_help_names_every_option_with_its_default():
    for key, value in DEFAULTS.items():
        assert key in SIMULATE_OPTIONS_HELP, key
        if value is not None:
            assert f"{key} ({value:g}" in SIMULATE_OPTIONS_HELP, key
    r = CliRunner().invoke(cli, ["simulate", "--help"])
    assert r.exit_code == 0 and "miss_rate" in r.output and "camera_pitch_deg" in r.output
    options = [p for p in cli.commands["simulate"].params if p.param_type_name == "option"]
    assert {p.name for p in options} >= {"scene", "laps", "seed", "width", "height", "sets"}
    assert all(p.help for p in options), [p.name for p in options if not p.help]


def test_simulate_reports_progress_per_frame(tmp_path):
    calls = []
    simulate(tmp_path / "s", scene="tiny", laps=2, width=32, height=24, frames_per_room=3,
             progress=lambda done, total: calls.append((done, total)))
    assert calls == [(k, 6) for k in range(1, 7)]


def test_one_of_each_is_singular(tmp_path):
    from ltc_cli.map.model import SemanticMap
    from ltc_cli.map.store import save_map
    from tests.sample_maps import SESSION, add

    m = SemanticMap.new(["chair", "table"])
    m.sessions = [dict(SESSION)]
    m.frame_keys = {"rec/000001"}
    add(m, [1, 1, 0.4], 0.0, [0.5, 0.5, 0.8], "chair", 0.8)
    save_map(m, tmp_path / "m.h5")
    r = CliRunner().invoke(cli, ["info", str(tmp_path / "m.h5")])
    assert r.output.splitlines()[-1] == f"{tmp_path / 'm.h5'}: 1 object of 1 class from 1 frame in 1 session"
    r = CliRunner().invoke(cli, ["query", str(tmp_path / "m.h5")])
    header = r.stdout.splitlines()[0]
    for word in ("defined", "detections", "missed", "last session", "last frame"):
        assert word in header
    for cryptic in (" def ", " det ", "nondet"):
        assert cryptic not in f" {header} "


def test_local_geojson_says_it_is_not_longitude_latitude(tmp_path):
    import json

    from ltc_cli.map.store import save_map
    from tests.sample_maps import hand_map

    save_map(hand_map(), tmp_path / "m.h5")
    r = CliRunner().invoke(cli, ["export", str(tmp_path / "m.h5"), "--format", "geojson"])
    doc = json.loads(r.stdout)
    assert doc["ltc:crs"] == "local-metres" and "NOT longitude/latitude" in doc["ltc:note"]
    assert "not lon/lat" in r.stderr
    r = CliRunner().invoke(cli, ["export", str(tmp_path / "m.h5"), "--format", "geojson", "--origin", "36.7,-4.4"])
    assert "ltc:note" not in json.loads(r.stdout)

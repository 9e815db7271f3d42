import copy
import json
import math

import jsonschema
import pytest
import yaml
from click.testing import CliRunner

from ltc_cli.cli import cli
from ltc_cli.config import defaults, load_config, parse_set, schema, settings_from
from ltc_cli.errors import ConfigError
from tests.recording import write_recording


def test_defaults_are_valid_and_documented():
    cfg = load_config()
    assert cfg == defaults()
    assert cfg["association"]["threshold_same_class"] == 0.4 and cfg["maintenance"]["v_other"] == 0.5


def test_set_parses_yaml_values():
    assert parse_set("a.b=0.5") == {"a": {"b": 0.5}}
    assert parse_set("a=null") == {"a": None}
    assert parse_set("a=[x, y]") == {"a": ["x", "y"]}
    with pytest.raises(ConfigError):
        parse_set("novalue")


def test_mapping_settings(tmp_path):
    f = tmp_path / "c.yaml"
    f.write_text("modeling:\n  class_depth: {}\n")
    assert load_config(f)["modeling"]["class_depth"] == {}  # a file replaces the table whole
    cfg = load_config(None, ["detector.options.model=x.onnx", "detector.options.score_threshold=0.3"])
    assert cfg["detector"]["options"] == {"model": "x.onnx", "score_threshold": 0.3}  # --set adds keys
    # ... and --set TABLE={} empties the table (it used to add nothing, so the default stayed on).
    cfg = load_config(None, ["modeling.class_depth={}", "modeling.taller_than={}"])
    assert cfg["modeling"]["class_depth"] == {} and cfg["modeling"]["taller_than"] == {}
    assert load_config(None, ["modeling.class_depth={tv: 0.2}"])["modeling"]["class_depth"]["chair"] == 0.5


def test_set_reaches_into_a_tables_entries_and_takes_them_out(tmp_path):
    """--set changes one field of a per-class entry, keeping the rest of the entry and the table;
    null takes an entry out of a table whose values cannot be null, and is a value where they can."""
    refrigerator = {"height": 1.2, "is": "next"}
    cfg = load_config(None, ["modeling.top_under.sink.height=0.85"])
    assert cfg["modeling"]["top_under"] == {"refrigerator": refrigerator, "sink": {"height": 0.85, "is": "next"}}
    assert load_config(None, ["modeling.top_under.sink=null"])["modeling"]["top_under"] == {"refrigerator": refrigerator}
    depth = load_config(None, ["modeling.class_depth.tv=null"])["modeling"]["class_depth"]
    assert "tv" not in depth and depth["chair"] == 0.5
    outgrow = load_config(None, ["integration.partial_outgrow.couch=null"])["integration"]["partial_outgrow"]
    assert outgrow["couch"] is None and outgrow["bed"] == 0.2  # null is a value of this table
    assert load_config(None, ["detector.options.threads=null"])["detector"]["options"] == {"threads": None}
    # A whole entry given by --set still replaces what it names and adds a new one.
    cfg = load_config(None, ["modeling.taller_than.toilet={height: 0.95, is: next}"])
    assert cfg["modeling"]["taller_than"]["toilet"] == {"height": 0.95, "is": "next"}
    assert cfg["modeling"]["taller_than"]["laptop"] == {"height": 0.35, "is": "tv"}
    # A file still replaces the table whole.
    f = tmp_path / "c.yaml"
    f.write_text("modeling:\n  top_under: {sink: {height: 0.7, is: next}}\n")
    assert load_config(f)["modeling"]["top_under"] == {"sink": {"height": 0.7, "is": "next"}}
    with pytest.raises(ConfigError, match="modeling.top_under.sink.height"):
        load_config(None, ["modeling.top_under.sink.height=-1"])


@pytest.mark.parametrize("item, message", [
    ("modeling.eps=abc", "must be a number"),
    ("modeling.nope=1", "unknown setting 'modeling.nope'"),
    ("maintenance.v_other=1.5", "between 0 and 1"),
    ("association.merge=3", "true or false"),
    ("modeling.clustering=kmeans", "grid, voxel or dbscan"),
    ("integration.max_weight=0", ">= 1 or null"),
])
def test_bad_settings_are_clear(item, message):
    with pytest.raises(ConfigError, match=message):
        load_config(None, [item])


def test_bad_config_file_names_it(tmp_path):
    f = tmp_path / "c.yaml"
    f.write_text("modeling: [1, 2\n")
    with pytest.raises(ConfigError) as err:
        load_config(f)
    assert str(f) in str(err.value) and "not valid YAML" in str(err.value)


# -- the settings schema --------------------------------------------------------------------------


def test_schema_is_valid_and_describes_every_default():
    s = schema()
    assert s["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    jsonschema.Draft202012Validator.check_schema(s)
    d = defaults()
    assert set(s["properties"]) == set(s["required"]) == set(d)
    for section, values in d.items():
        node = s["properties"][section]
        # Every section has fixed keys: all of them described, required, and no others allowed.
        assert node["additionalProperties"] is False, section
        assert set(node["properties"]) == set(node["required"]) == set(values), section


def test_numbers_are_typed_as_the_schema_says():
    cfg = load_config(None, ["modeling.border=12.0", "association.threshold_same_class=1"])
    assert cfg["modeling"]["border"] == 12 and type(cfg["modeling"]["border"]) is int
    assert cfg["association"]["threshold_same_class"] == 1.0
    assert type(cfg["association"]["threshold_same_class"]) is float


@pytest.mark.parametrize("item, key, message", [
    ("modeling.thin_fraction=-3", "modeling.thin_fraction", "between 0 and 1, got -3"),
    ("association.threshold_same_class=-0.1", "association.threshold_same_class", ">= 0, got -0.1"),
    ("association.threshold_other_class=.nan", "association.threshold_other_class", "finite number >= 0, got nan"),
    ("association.threshold_same_class=.inf", "association.threshold_same_class", "finite number >= 0, got inf"),
    ("maintenance.min_visible_pixels=-5", "maintenance.min_visible_pixels", "integer >= 0, got -5"),
    ("maintenance.min_visible_fraction=1.5", "maintenance.min_visible_fraction", "between 0 and 1 or null"),
    ("index.cell_size=0", "index.cell_size", "> 0, got 0"),
    ("modeling.border=10.5", "modeling.border", "an integer >= 0, got 10.5"),
    ("modeling.class_depth.chair=-1", "modeling.class_depth.chair", "> 0, got -1"),
    ("maintenance.v_other_per_class.chair=1", "maintenance.v_other_per_class.chair", "strictly between 0 and 1"),
    ("modeling.floor_classes=[chair, 3]", "modeling.floor_classes[1]", "string, got 3"),
    ("modeling.min_depth=7", "modeling.min_depth", "below modeling.max_depth"),
    ("modeling=3", "modeling", "must be a mapping"),
])
def test_out_of_range_settings_name_the_key(item, key, message):
    with pytest.raises(ConfigError) as err:
        load_config(None, [item])
    text = str(err.value)
    assert text.startswith(f"--set {item}: setting {key}") and message in text and "\n" not in text


def test_nan_passes_jsonschema_minimum_so_it_is_refused_explicitly():
    # The reason for ltc's own number type: plain jsonschema lets NaN through every bound.
    plain = jsonschema.Draft202012Validator({"type": "number", "minimum": 0, "maximum": 1})
    assert plain.is_valid(math.nan)
    with pytest.raises(ConfigError, match="finite"):
        load_config(None, ["modeling.thin_fraction=.nan"])


def test_unknown_key_suggests_the_near_one(tmp_path):
    f = tmp_path / "c.yaml"
    f.write_text("association:\n  threshold_same: 0.3\n")
    with pytest.raises(ConfigError) as err:
        load_config(f)
    assert str(err.value) == (f"{f}: unknown setting 'association.threshold_same' "
                              f"(did you mean association.threshold_same_class?)")


def test_error_names_where_the_value_came_from(tmp_path):
    f = tmp_path / "c.yaml"
    f.write_text("modeling:\n  eps: -1\n")
    with pytest.raises(ConfigError) as err:
        load_config(f)
    assert str(err.value).startswith(f"{f}: setting modeling.eps: must be a number > 0")
    with pytest.raises(ConfigError) as err:  # a --set after the file fixes eps and breaks min_samples
        load_config(f, ["modeling.eps=0.2", "modeling.min_samples=0"])
    assert str(err.value).startswith("--set modeling.min_samples=0: setting modeling.min_samples")
    f.write_text("- modeling\n")
    with pytest.raises(ConfigError, match="must be a mapping of sections"):
        load_config(f)


def test_settings_from_copies_and_checks():
    cfg = defaults()
    before = copy.deepcopy(cfg)
    out = settings_from(cfg, {"maintenance": {"v_other": 0.3, "v_other_per_class": {"chair": 0.8}}})
    assert cfg == before  # the caller's dict is not written into
    assert out["maintenance"]["v_other"] == 0.3 and out["maintenance"]["v_other_per_class"] == {"chair": 0.8}
    out["modeling"]["class_depth"]["chair"] = 9.0
    assert cfg["modeling"]["class_depth"]["chair"] == 0.5  # nothing shared
    cfg["index"]["cell_size"] = 0.0
    with pytest.raises(ConfigError, match=r"^setting index.cell_size: must be a number > 0, got 0.0$"):
        settings_from(cfg)


@pytest.fixture(scope="module")
def tiny_recording(tmp_path_factory):
    return write_recording(tmp_path_factory.mktemp("rec"), cam_ys=(0.0,))


@pytest.mark.parametrize("item, key", [
    ("modeling.epsilon=0.2", "'modeling.epsilon'"),            # unknown key
    ("association.merge=maybe", "association.merge"),          # wrong type
    ("modeling.thin_fraction=-3", "modeling.thin_fraction"),   # negative
    ("association.threshold_same_class=.nan", "association.threshold_same_class"),  # NaN
    ("index.cell_size=0", "index.cell_size"),                  # zero where it divides
])
def test_cli_bad_setting_is_one_line_exit_1(tiny_recording, tmp_path, item, key):
    m = tmp_path / "m.h5"
    for args in (["ingest", str(tiny_recording), "--map", str(m), "--set", item],
                 ["calibrate", str(tiny_recording), "-o", str(tmp_path / "c.yaml"), "--set", item]):
        r = CliRunner().invoke(cli, args)
        lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
        assert r.exit_code == 1, r.output
        assert len(lines) == 1 and key in lines[0] and f"--set {item}" in lines[0], r.stderr
        assert "Traceback" not in r.output and isinstance(r.exception, SystemExit)  # a clean exit
    assert not m.exists() and not (tmp_path / "c.yaml").exists()


def test_cli_bad_config_file_is_one_line(tiny_recording, tmp_path):
    f = tmp_path / "c.yaml"
    f.write_text(yaml.safe_dump({"maintenance": {"min_visible_pixels": -5}}))
    r = CliRunner().invoke(cli, ["ingest", str(tiny_recording), "--map", str(tmp_path / "m.h5"), "--config", str(f)])
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.exit_code == 1 and len(lines) == 1
    assert lines[0] == f"Error: {f}: setting maintenance.min_visible_pixels: must be an integer >= 0, got -5"


def test_ingest_does_not_write_into_the_callers_config(tmp_path):
    from ltc_cli.ingest.session import ingest
    from ltc_cli.map.store import load_map

    cfg = defaults()
    before = copy.deepcopy(cfg)
    calibration = {"format": "ltc-calibration/1", "detector": "recorded", "v_other": 0.3,
                   "per_class": {"chair": {"v_other": 0.8}, "tv": {"v_other": None}}}
    ingest([write_recording(tmp_path / "rec")], tmp_path / "m.h5", cfg, calibration=calibration)
    assert cfg == before
    # ... while the session ran with the calibration's values.
    row = load_map(tmp_path / "m.h5").sessions[0]
    assert row["v_other"] == 0.3
    assert json.loads(row["settings"])["maintenance"]["v_other_per_class"] == {"chair": 0.8}


def test_the_settings_type_names_every_key_of_the_schema():
    """ltc_cli.settings types what config.schema.json checks: the same sections and keys."""
    from typing import get_type_hints

    from ltc_cli.config import schema
    from ltc_cli.settings import Settings

    sections = get_type_hints(Settings)
    props = schema()["properties"]
    assert set(sections) == set(props)
    for name, section in sections.items():
        assert set(get_type_hints(section)) == set(props[name]["properties"]), name
    assert set(sections) == set(defaults())

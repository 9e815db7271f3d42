import pytest

from ltc_cli.config import defaults, load_config, parse_set
from ltc_cli.errors import ConfigError


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

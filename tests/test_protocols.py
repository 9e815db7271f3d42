"""Plugin interfaces (ltc_cli/protocols.py) and plugin options by JSON Schema (ltc_cli/validation.py)."""

import math
import typing

import jsonschema
import numpy as np
import pytest

from ltc_cli import hookspecs, plugins, protocols
from ltc_cli.errors import ConfigError, PluginError
from ltc_cli.recordings.open import open_recording
from ltc_cli.validation import check_options
from tests.recording import write_recording


def test_hook_specs_name_the_protocols():
    expected = {
        "register_detectors": typing.Callable[[str, protocols.DetectorFactory], None],
        "register_metrics": typing.Callable[[str, protocols.MetricFactory], None],
        "register_policies": typing.Callable[[str, protocols.PolicyFactory], None],
        "register_readers": typing.Callable[[str, protocols.Reader], None],
    }
    for hook, annotation in expected.items():
        hints = typing.get_type_hints(getattr(hookspecs, hook))
        assert hints["register"] == annotation, hook
        assert "ltc_cli.protocols" in getattr(hookspecs, hook).__doc__, hook


def test_builtins_follow_the_protocols(tmp_path):
    for name, reg in plugins.registry("readers").items():
        assert isinstance(reg.factory, protocols.Reader), name
    for name, reg in plugins.registry("metrics").items():
        assert isinstance(reg.factory({}), protocols.Metric), name
    for name, reg in plugins.registry("policies").items():
        policy = reg.factory({})
        assert isinstance(policy, protocols.Policy), name
        out = policy.non_detections(np.array([True, False]), np.array([5000.0, 5000.0]), np.array([1000.0, 1000.0]))
        assert out.shape == (2,) and out.dtype == bool and not out[0], name  # a matched object never
    rec = open_recording(write_recording(tmp_path / "rec", cam_ys=(0.0,)))
    det = plugins.get("detectors", "recorded").factory(rec, {})
    assert isinstance(det, protocols.Detector) and det.classes == ["chair", "table", "tv"]
    assert not isinstance(object(), protocols.Detector)


SCHEMA = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "type": "object",
    "required": ["model"],
    "additionalProperties": False,
    "properties": {
        "model": {"type": "string", "description": "the path to a model file"},
        "threshold": {"type": "number", "minimum": 0, "maximum": 1, "default": 0.5},
        "size": {"type": "integer", "minimum": 1},
    },
}


def test_check_options_fills_defaults_and_keeps_given_values():
    assert check_options({"model": "m"}, SCHEMA, "x") == {"model": "m", "threshold": 0.5}
    assert check_options({"model": "m", "threshold": 0, "size": 3}, SCHEMA, "x") == {
        "model": "m", "threshold": 0, "size": 3}
    assert check_options(None, {"type": "object"}, "x") == {}


@pytest.mark.parametrize(
    "options, message",
    [
        ({}, "x: option 'model' is required: the path to a model file"),
        ({"model": "m", "treshold": 0.3}, "x: unknown option(s) 'treshold' (known: model, threshold, size)"),
        ({"model": "m", "threshold": 1.5}, "x: option 'threshold': 1.5 is greater than the maximum of 1"),
        ({"model": "m", "threshold": math.nan}, "x: option 'threshold': nan is not a finite number"),
        ({"model": "m", "threshold": math.inf}, "x: option 'threshold': inf is not a finite number"),
        ({"model": "m", "size": 2.5}, "x: option 'size': 2.5 is not of type 'integer'"),
        ({"model": "m", "size": True}, "x: option 'size': True is not of type 'integer'"),
        ("model=m", "x: options must be a mapping of option names to values, got 'model=m'"),
    ],
)
def test_check_options_errors_are_one_line_naming_the_option(options, message):
    with pytest.raises(ConfigError) as err:
        check_options(options, SCHEMA, "x")
    assert str(err.value) == message
    with pytest.raises(PluginError):
        check_options(options, SCHEMA, "x", PluginError)


def test_every_builtin_options_schema_is_valid_draft_2020_12():
    from ltc_plugins import recorded
    from ltc_plugins.onnx import maskrcnn, yolo_seg
    from ltc_plugins.readers import READERS
    from ltc_plugins.readers.ltc_recording import LtcRecordingReader

    schemas = [recorded.OPTIONS_SCHEMA, maskrcnn.OPTIONS_SCHEMA, yolo_seg.OPTIONS_SCHEMA,
               LtcRecordingReader.OPTIONS_SCHEMA] + [r.OPTIONS_SCHEMA for r in READERS]
    for schema in schemas:
        assert schema["$schema"] == "https://json-schema.org/draft/2020-12/schema"
        jsonschema.Draft202012Validator.check_schema(schema)
        assert schema["additionalProperties"] is False  # unknown options are errors


def test_recorded_detector_refuses_unknown_options(tmp_path):
    rec = open_recording(write_recording(tmp_path / "rec", cam_ys=(0.0,)))
    factory = plugins.get("detectors", "recorded").factory
    with pytest.raises(PluginError, match="unknown option.*'model'"):
        factory(rec, {"model": "yolo.onnx"})
    with pytest.raises(PluginError, match="no detections/ folder"):
        factory(rec, {"folder": str(tmp_path / "nowhere")})

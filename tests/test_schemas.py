"""Every schema in schemas/ is valid draft 2020-12, and malformed inputs to each are refused with a
message naming the file and the path of the problem inside it."""

import copy
import json
from importlib import resources

import jsonschema
import pytest
import yaml

from ltc_cli.errors import LtcError, SchemaError
from ltc_cli.validation import load_schema, validate

SCHEMAS = sorted(p.name[: -len(".schema.json")]
                 for p in resources.files("ltc_cli.schemas").iterdir() if p.name.endswith(".schema.json"))


def test_every_format_has_a_schema():
    for name in ("recording", "detections", "ground_truth", "calibration", "export", "geojson-export"):
        assert name in SCHEMAS


@pytest.mark.parametrize("name", SCHEMAS)
def test_schema_is_valid_draft_2020_12(name):
    schema = load_schema(name)
    assert schema["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    jsonschema.Draft202012Validator.check_schema(schema)


RECORDING = """\
format: ltc-recording/1
camera: {width: 640, height: 480, fx: 525.0, fy: 525.0, cx: 319.5, cy: 239.5}
depth: {scale: 1000.0, min: 0.3, max: 6.0}
up: -y
"""
DETECTIONS = {"frame": "000001", "instances": [
    {"class": "chair", "score": 0.9, "mask": {"size": [480, 640], "counts": "abc"}},
    {"class": "table", "scores": {"table": 0.7, "chair": 0.1}, "mask": {"size": [480, 640], "counts": [0, 5, 10]}},
]}
GROUND_TRUTH = {"format": "ltc-ground-truth/1", "objects": [
    {"id": 1, "class": "chair", "center": [1, 2, 0.45], "yaw": 0.1, "size": [0.5, 0.5, 0.9]},
    {"id": 2, "class": "table", "center": [0, 0, 0.4], "yaw": 0.0, "size": [1.2, 0.8, 0.8]},
]}
CALIBRATION = """\
format: ltc-calibration/1
detector: recorded
v_other: 0.42
recall: 0.7
precision: 0.8
"""


def edit(doc, path, value):
    """A copy of doc with the value at path (a list of keys / indices) replaced; None deletes it."""
    doc = copy.deepcopy(doc)
    node = doc
    for k in path[:-1]:
        node = node[k]
    if value is None:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return doc


CASES = [
    # (schema, valid document, path to break, bad value, expected "at ..." location)
    ("recording", yaml.safe_load(RECORDING), ["camera", "fx"], -525.0, "camera.fx"),
    ("recording", yaml.safe_load(RECORDING), ["camera", "width"], "640", "camera.width"),
    ("recording", yaml.safe_load(RECORDING), ["depth", "scale"], None, "depth"),
    ("recording", yaml.safe_load(RECORDING), ["up"], "sideways", "up"),
    ("recording", yaml.safe_load(RECORDING), ["format"], "ltc-recording/2", "format"),
    ("detections", DETECTIONS, ["instances", 1, "mask", "size"], [480], "instances.1.mask.size"),
    ("detections", DETECTIONS, ["instances", 0, "score"], 1.5, "instances.0.score"),
    ("detections", DETECTIONS, ["instances", 1, "class"], "", "instances.1.class"),
    ("detections", DETECTIONS, ["instances", 0, "colour"], "red", "instances.0"),
    ("ground_truth", GROUND_TRUTH, ["objects", 1, "center"], [0, 0], "objects.1.center"),
    ("ground_truth", GROUND_TRUTH, ["objects", 0, "size", 2], -1.0, "objects.0.size.2"),
    ("ground_truth", GROUND_TRUTH, ["objects", 1, "yaw"], None, "objects.1"),
    ("calibration", yaml.safe_load(CALIBRATION), ["v_other"], 1.5, "v_other"),
    ("calibration", yaml.safe_load(CALIBRATION), ["recall"], "high", "recall"),
    ("calibration", yaml.safe_load(CALIBRATION), ["v_other"], None, "(top level)"),
]


@pytest.mark.parametrize("name,doc,path,value,where", CASES,
                         ids=[f"{c[0]}:{'.'.join(map(str, c[2]))}" for c in CASES])
def test_malformed_input_names_the_file_and_the_path(name, doc, path, value, where):
    validate(doc, name, "good.file")  # the untouched document is fine
    with pytest.raises(SchemaError) as err:
        validate(edit(doc, path, value), name, f"/data/{name}.in")
    msg = str(err.value)
    assert msg.startswith(f"/data/{name}.in: at {where}: "), msg
    assert "\n" not in msg


# -- the same through the readers that load these files ------------------------------------------

def test_reader_refuses_a_bad_recording_yaml(tmp_path):
    from ltc_cli.recordings.open import open_recording

    rec = tmp_path / "rec"
    rec.mkdir()
    (rec / "recording.yaml").write_text(RECORDING.replace("fx: 525.0", "fx: -1"))
    (rec / "poses.txt").write_text("")
    with pytest.raises(LtcError) as err:
        open_recording(rec)
    assert str(err.value).startswith(f"{rec / 'recording.yaml'}: at camera.fx: ")


def test_calibration_loader_refuses_a_bad_file(tmp_path):
    from ltc_cli.tools.calibration_file import load_calibration

    p = tmp_path / "calibration.yaml"
    p.write_text(CALIBRATION.replace("v_other: 0.42", "v_other: 1.2"))
    with pytest.raises(LtcError) as err:
        load_calibration(p)
    assert str(err.value).startswith(f"{p}: at v_other: ")


def test_ground_truth_loader_refuses_a_bad_file(tmp_path):
    from ltc_cli.map.render import load_ground_truth

    p = tmp_path / "ground_truth.json"
    p.write_text(json.dumps(edit(GROUND_TRUTH, ["objects", 1, "class"], 7)))
    with pytest.raises(LtcError) as err:
        load_ground_truth(tmp_path)  # a recording folder holding it
    assert str(err.value).startswith(f"{p}: at objects.1.class: ")
    ok = tmp_path / "ok.json"
    ok.write_text(json.dumps(GROUND_TRUTH))
    assert len(load_ground_truth(ok)) == 2


def test_recorded_detector_skips_a_bad_detections_file(tmp_path):
    """A malformed detections/<frame>.json is a FrameError (the frame is skipped) naming the file
    and the path inside it."""
    from ltc_cli import plugins
    from ltc_cli.errors import FrameError
    from ltc_cli.recordings.open import open_recording
    from tests.recording import write_recording

    rec = write_recording(tmp_path / "rec", cam_ys=(0.0,))
    det_file = rec / "detections" / "000000.json"
    doc = json.loads(det_file.read_text())
    doc["instances"][0]["score"] = 2.0
    det_file.write_text(json.dumps(doc))
    recording = open_recording(rec)
    detector = plugins.get("detectors", "recorded").factory(recording, {})
    frame = recording.frames[0].load()
    with pytest.raises(FrameError) as err:
        detector.detect(frame)
    assert str(err.value).startswith(f"{det_file}: at instances.0.score: ")

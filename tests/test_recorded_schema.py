"""The recorded detector checks each frame's file against schemas/detections.schema.json with the
score vectors checked in one pass (plugins/recorded.py, ``check_detections``): it accepts and
refuses exactly what jsonschema does with the full schema, with the full schema's message."""

import copy
import json

import pytest

from ltc_cli.errors import SchemaError
from ltc_cli.validation import FiniteValidator, load_schema, validate
from ltc_plugins.recorded import PROBABILITY, check_detections

GOOD = {
    "frame": "000001", "detector": "onnx-yolo-seg",
    "instances": [
        {"class": "cup", "score": 0.9, "scores": {"cup": 0.9, "bowl": 0.05, "book": 0, "tv": 1},
         "mask": {"size": [2, 3], "counts": "15"}},
        {"class": "tv", "scores": {"tv": 0.5}, "mask": {"size": [2, 3], "counts": [6]}},
        {"class": "book", "id": 3},
    ],
}


def changed(path, value):
    """GOOD with the value at ``path`` (keys and indices) replaced; ``...`` deletes it."""
    doc = copy.deepcopy(GOOD)
    *head, last = path
    node = doc
    for key in head:
        node = node[key]
    if value is ...:
        del node[last]
    else:
        node[last] = value
    return doc


CASES = {
    "good": GOOD,
    "no scores": changed(("instances", 0, "scores"), ...),
    "empty scores": changed(("instances", 1, "scores"), {}),
    "a score above one": changed(("instances", 0, "scores", "bowl"), 1.5),
    "a negative score": changed(("instances", 1, "scores", "tv"), -0.1),
    "a NaN score": json.loads(json.dumps(changed(("instances", 0, "scores", "cup"), float("nan")))),
    "an infinite score": changed(("instances", 0, "scores", "cup"), float("inf")),
    "a true score": changed(("instances", 0, "scores", "book"), True),
    "a string score": changed(("instances", 0, "scores", "book"), "0.5"),
    "a null score": changed(("instances", 0, "scores", "book"), None),
    "scores as a list": changed(("instances", 0, "scores"), [0.9, 0.1]),
    "a top score above one": changed(("instances", 0, "score"), 2),
    "no class": changed(("instances", 2, "class"), ...),
    "an unknown key": changed(("instances", 1, "colour"), "red"),
    "a bad mask size": changed(("instances", 0, "mask", "size"), [2]),
    "no instances": changed(("instances",), ...),
}


def test_the_fast_check_is_in_use():
    # Were the schema's score vectors to hold anything else, every document would take the full
    # schema: right, but not what this file tests.
    scores = load_schema("detections")["properties"]["instances"]["items"]["properties"]["scores"]
    assert scores["additionalProperties"] == PROBABILITY


@pytest.mark.parametrize("name", list(CASES))
def test_accepts_and_refuses_what_the_full_schema_does(name):
    doc = CASES[name]
    full = FiniteValidator(load_schema("detections"))
    if full.is_valid(doc):
        assert name in ("good", "no scores", "empty scores")
        check_detections(doc, "f.json")
        return
    with pytest.raises(SchemaError) as fast:
        check_detections(doc, "f.json")
    with pytest.raises(SchemaError) as slow:
        validate(doc, "detections", "f.json")
    assert str(fast.value) == str(slow.value) and "f.json" in str(fast.value)

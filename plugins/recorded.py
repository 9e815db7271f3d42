"""Detector ``recorded``: the detections stored in a recording's detections/ folder.

Any external detector (or ground truth) can be replayed this way: one JSON file per frame with
instances (class, score or full score vector, COCO RLE mask or a PNG of instance ids). A file that
breaks its schema (a score outside [0, 1] or not a finite number, ...) makes its frame unusable
(FrameError); a class that the recording's class list does not hold is a warning of the frame.
The one option, ``folder``, names another folder of detection files. A classes.json there (written
by ``detector.save_to``, ltc_cli/recordings/saved_detections.py) gives the vocabulary, in the order
of the detector that wrote the files.
"""

from __future__ import annotations

import copy
import json
from functools import lru_cache
from pathlib import Path

import numpy as np
from PIL import Image

from ltc_cli import hookimpl
from ltc_cli.recordings import rle
from ltc_cli.recordings.saved_detections import CLASSES_FILE, recording_folder
from ltc_cli.errors import FrameError, PluginError
from ltc_cli.validation import FiniteValidator, check_options, load_schema, validate
from ltc_cli.types import Detection, Frame, FrameWarning

OPTIONS_SCHEMA = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "type": "object",
    "additionalProperties": False,
    "properties": {
        "folder": {"type": ["string", "null"], "minLength": 1, "default": None,
                   "description": "folder of the detection files (default: the recording's detections/); "
                                  "{recording} in it: the recording folder's name"},
    },
}  # fmt: skip


class RecordedDetector:
    # detect() only reads files, so ingest --jobs may run it on several frames at once.
    thread_safe = True
    # The detections are read from files: the frame's colour image is never decoded (Frame.rgb).
    needs_rgb = False

    def __init__(self, folder: Path, classes: list[str]):
        self.folder = folder
        self.classes = classes
        self._index = {c: i for i, c in enumerate(classes)}

    @classmethod
    def from_options(cls, recording, options: dict) -> "RecordedDetector":
        options = check_options(options, OPTIONS_SCHEMA, "detector 'recorded'", PluginError)
        given = options["folder"]
        folder = recording_folder(given, recording) if given else Path(recording.path) / "detections"
        if not folder.is_dir():
            raise PluginError("no detections/ folder: record detections or choose a model detector", folder)
        classes = _saved_classes(folder) or list(recording.classes or [])
        if not classes:
            # No class list in the recording: the vocabulary is every class the files mention.
            seen = set()
            for p in sorted(folder.glob("*.json")):
                try:
                    doc = json.loads(p.read_text())
                    seen.update(inst["class"] for inst in doc.get("instances", []) if isinstance(inst, dict) and "class" in inst)
                except (OSError, ValueError, AttributeError):
                    continue  # reported when that frame is read
            classes = sorted(seen)
        return cls(folder, classes)

    def detect(self, frame: Frame) -> list[Detection]:
        path = self.folder / f"{frame.key}.json"
        if not path.is_file():
            raise FrameError("no recorded detections for this frame", path)
        try:
            doc = json.loads(path.read_text())
        except (OSError, UnicodeDecodeError, ValueError) as exc:
            raise FrameError(f"not valid JSON ({exc})", path) from None
        try:
            check_detections(doc, path)
        except Exception as exc:  # SchemaError for one frame: skip the frame, keep the map
            raise FrameError(exc.message if hasattr(exc, "message") else str(exc), path) from None
        h, w = frame.depth_m.shape
        ids_img = None
        if doc.get("masks_png"):
            png = self.folder / doc["masks_png"]
            try:
                ids_img = np.asarray(Image.open(png))
            except (OSError, ValueError) as exc:
                raise FrameError(f"cannot read instance-id PNG ({exc})", png) from None
            if ids_img.shape[:2] != (h, w):
                raise FrameError(f"instance-id PNG is {ids_img.shape[1]}x{ids_img.shape[0]}, frame is {w}x{h}", png)
        out = []
        for n, inst in enumerate(doc["instances"]):
            if "mask" in inst:
                try:
                    mask = rle.decode(inst["mask"])
                except (ValueError, KeyError) as exc:
                    raise FrameError(f"instances.{n}.mask: {exc}", path) from None
                if mask.shape != (h, w):
                    raise FrameError(f"instances.{n}.mask is {mask.shape[1]}x{mask.shape[0]}, frame is {w}x{h}", path)
            elif ids_img is not None and "id" in inst:
                mask = ids_img == inst["id"]
            else:
                raise FrameError(f"instances.{n} has no mask (give mask, or masks_png and id)", path)
            scores = np.zeros(len(self.classes))
            for name in dict.fromkeys([inst["class"], *inst.get("scores", {})]):
                if name not in self._index:
                    # Only possible when the recording lists the classes (recording.yaml, -r classes=; else
                    # every class named in the files is in the vocabulary); said once per class.
                    frame.warnings.append(FrameWarning(
                        f"class {name!r} is not in the recording's class list: its scores are ignored",
                        str(path), once=f"class:{name}",
                    ))  # fmt: skip
            if "scores" in inst:
                for name, p in inst["scores"].items():
                    if name in self._index:
                        scores[self._index[name]] = p
            if inst["class"] in self._index and scores[self._index[inst["class"]]] == 0:
                scores[self._index[inst["class"]]] = inst.get("score", 1.0)
            if mask.any() and scores.sum() > 0:
                out.append(Detection(mask, scores))
        return out


#: A probability of schemas/detections.schema.json's score vectors.
PROBABILITY = {"type": "number", "minimum": 0, "maximum": 1}


@lru_cache(maxsize=None)
def _without_scores():
    """The detections schema with each score vector checked only as an object, or None when the
    schema's vectors hold something else than PROBABILITY (then the full schema checks them)."""
    schema = copy.deepcopy(load_schema("detections"))
    scores = schema["properties"]["instances"]["items"]["properties"]["scores"]
    if scores.get("additionalProperties") != PROBABILITY:
        return None
    scores["additionalProperties"] = True
    return FiniteValidator(schema)


def _probabilities(scores: dict) -> bool:
    # bool is not a JSON number (type(True) is bool), and NaN and infinities fail the comparisons.
    return all(type(p) in (int, float) and 0 <= p <= 1 for p in scores.values())


def check_detections(doc, path) -> None:
    """Raise SchemaError when a frame's detections document breaks schemas/detections.schema.json,
    naming its first problem. jsonschema checks a full score vector (80 classes) key by key, 2 ms a
    frame of a replay that maps in about 15; the vectors are checked in one pass here instead, and
    only a document that fails goes through the full schema, for its message."""
    fast = _without_scores()
    if fast is not None and fast.is_valid(doc) and all(_probabilities(inst.get("scores", {}))
                                                       for inst in doc["instances"]):
        return
    validate(doc, "detections", path)


def _saved_classes(folder: Path) -> list[str] | None:
    """The vocabulary a detector wrote beside its detections (``detector.save_to``), in its order,
    so that a replay's score vectors are the detector's; None when there is none."""
    path = folder / CLASSES_FILE
    if not path.is_file():
        return None
    try:
        classes = json.loads(path.read_text(encoding="utf-8"))["classes"]
    except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError) as exc:
        raise PluginError(f"not a class list written by detector.save_to ({exc})", path) from None
    if not isinstance(classes, list) or not classes or not all(isinstance(c, str) and c for c in classes) \
            or len(set(classes)) != len(classes):
        raise PluginError("not a class list written by detector.save_to (classes: distinct names)", path)
    return classes


@hookimpl
def register_detectors(register):
    register("recorded", RecordedDetector.from_options)

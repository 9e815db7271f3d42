"""A detector's detections written as the ``recorded`` detector reads them (``detector.save_to``).

A model detector costs most of an ingest (YOLOv8n-seg on a CPU: about 25 ms a frame). A user who
tunes the settings on their own recording, or who detects on a machine with a GPU and maps on
another, runs the model once with ``--set detector.save_to=DIR``: every frame the ingest detects
is written to ``DIR/<frame>.json`` (schemas/detections.schema.json: class, score, the score vector,
the mask as COCO RLE), and ``DIR/classes.json`` holds the detector's vocabulary in its order.
``--detector recorded --set detector.options.folder=DIR`` then replays exactly those detections
(plugins/recorded.py reads classes.json), so the map is the one the model makes.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ltc_cli import plugins
from ltc_cli.errors import ConfigError, LtcError
from ltc_cli.fileio import write_text_atomic
from ltc_cli.recordings import rle

#: The detector's vocabulary, beside the frames' files.
CLASSES_FILE = "classes.json"
#: In ``save_to`` (and the recorded detector's ``folder``): the recording folder's name, so that the
#: recordings of one ingest (or of one ingest-many map) each get their own folder.
RECORDING_FIELD = "{recording}"


def recording_folder(template, recording) -> Path:
    """``template`` with ``{recording}`` replaced by the name of ``recording``'s folder."""
    return Path(str(template).replace(RECORDING_FIELD, Path(recording.path).name))


class DetectionsWriteError(LtcError):
    """A frame's detections that cannot be written where ``detector.save_to`` says."""


def detections_doc(frame_key: str, detector: str, detections, classes: list[str]) -> dict:
    """One frame's detections as a detections/<frame>.json document: each instance's top class
    and score, every class it scored above zero (exact floats), and its mask (RLE)."""
    instances = []
    for det in detections:
        scores = np.asarray(det.scores, dtype=np.float64)
        top = int(np.argmax(scores)) if scores.size else 0
        instances.append({
            "class": classes[top],
            "score": float(scores[top]) if scores.size else 0.0,
            "scores": {classes[k]: float(scores[k]) for k in np.flatnonzero(scores > 0)},
            "mask": rle.encode(np.asarray(det.mask, dtype=bool)),
        })
    return {"frame": frame_key, "detector": detector, "instances": instances}


class SavingDetector:
    """A detector that also writes each frame's detections to ``folder`` (see the module)."""

    def __init__(self, inner, folder: Path, name: str):
        self.inner, self.folder, self.name = inner, Path(folder), name
        self.classes = list(inner.classes)
        self.needs_rgb = getattr(inner, "needs_rgb", True)
        self.thread_safe = getattr(inner, "thread_safe", False)

    def detect(self, frame):
        detections = self.inner.detect(frame)
        path = self.folder / f"{frame.key}.json"
        try:
            write_text_atomic(path, json.dumps(detections_doc(frame.key, self.name, detections, self.classes)))
        except OSError as exc:
            raise DetectionsWriteError(f"cannot write the frame's detections (detector.save_to): "
                                       f"{exc.strerror or exc}", path) from None
        return detections


def detector_for(recording, detector_settings: dict):
    """The detector the settings' ``detector`` section names, made for ``recording``; with
    ``save_to``, wrapped to write its detections there (the folder and classes.json made now, so
    that a folder that cannot be written stops the ingest before its first frame)."""
    det = plugins.get("detectors", detector_settings["name"]).factory(recording, dict(detector_settings["options"]))
    folder = detector_settings.get("save_to")
    if folder is None:
        return det
    folder = recording_folder(folder, recording)
    doc = {"detector": detector_settings["name"], "classes": list(det.classes), "recording": recording.identity}
    _check_same_recording(folder / CLASSES_FILE, recording.identity)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        write_text_atomic(folder / CLASSES_FILE, json.dumps(doc, indent=1) + "\n")
    except OSError as exc:
        raise ConfigError(f"detector.save_to: cannot write there ({exc.strerror or exc})", folder) from None
    return SavingDetector(det, folder, detector_settings["name"])


def _check_same_recording(classes_file: Path, identity: str) -> None:
    """A folder already written for another recording is not written into: frames of one name
    (000000.json) would silently replace that recording's (two laps of ``ltc ingest-many`` with one
    ``detector.save_to``). The same recording again (a re-run, a revisit) is fine."""
    try:
        earlier = json.loads(classes_file.read_text(encoding="utf-8")).get("recording")
    except (OSError, UnicodeDecodeError, ValueError, AttributeError):
        return  # none yet (or not ours to judge): written anew below
    if earlier is not None and earlier != identity:
        raise ConfigError(f"detector.save_to: this folder holds another recording's detections ({earlier}, not "
                          f"{identity}); give each recording its own folder", classes_file.parent)

"""The calibration file (``ltc-calibration/1``): the :class:`Calibration` that ``ltc calibrate``
measures, its document, writing and reading it, and the settings it gives an ingest.

How the figures are measured and why v_Other is derived from them as it is: ltc_cli/tools/calibrate.py
and docs/calibration.md.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from ltc_cli import __version__
from ltc_cli.config import read_yaml
from ltc_cli.errors import LtcError
from ltc_cli.fileio import write_text_atomic
from ltc_cli.validation import validate

FORMAT = "ltc-calibration/1"
V_OTHER_MIN, V_OTHER_MAX = 0.05, 0.95
#: Pseudo-instances of the Beta prior that shrinks a class's rate towards the overall one.
PRIOR_INSTANCES = 10.0

METHOD = (
    "v_other = R clipped to [0.05, 0.95], R = the detector's class-agnostic detection rate on the "
    "ground-truth instances with at least min_pixels visible pixels (matched by mask IoU >= "
    "iou_threshold, greedy by IoU): a non-detection (eq. 4) votes 'gone' with the probability that the "
    "detector would have seen the object had it been there. Per class: (detected_c + 10 R) / "
    "(instances_c + 10), clipped. See docs/calibration.md."
)


class CalibrationError(LtcError):
    """The recording cannot be used for calibration (no annotations, no usable instance)."""


@dataclass
class InstanceOutcome:
    """One ground-truth instance in one frame and what the detector made of it."""

    frame: str
    gt_id: int
    gt_class: str
    pixels: int
    counted: bool  # enough pixels and a class in the detector's vocabulary
    detected_class: str | None  # top class of the matching detection; None = missed
    iou: float  # of the matching detection (0 when missed)
    score: float  # the detection's score for the true class (0 when missed)


@dataclass
class ClassStats:
    instances: int = 0  # counted ground-truth instances
    detected: int = 0  # of them, matched by a detection of any class
    tp: int = 0
    fp: int = 0
    fn: int = 0
    score_sum: float = 0.0  # sum of the true class's score over matched instances

    @property
    def recall(self) -> float | None:
        return self.tp / (self.tp + self.fn) if self.tp + self.fn else None

    @property
    def precision(self) -> float | None:
        return self.tp / (self.tp + self.fp) if self.tp + self.fp else None

    @property
    def detection_rate(self) -> float | None:
        return self.detected / self.instances if self.instances else None

    @property
    def mean_score(self) -> float | None:
        return self.score_sum / self.detected if self.detected else None


def clip_v_other(v: float) -> float:
    return float(min(V_OTHER_MAX, max(V_OTHER_MIN, v)))


def v_other_from_rate(detection_rate: float) -> float:
    """The module docstring's rule: v_Other = R, clipped to [0.05, 0.95]."""
    return clip_v_other(detection_rate)


@dataclass
class Calibration:
    """The measured response of a detector on one recording (see the module docstring)."""

    recording: str
    recording_identity: str
    detector: str
    detector_options: dict
    classes: list[str]
    min_pixels: int
    iou_threshold: float
    frames: int = 0  # frames evaluated
    frames_skipped: int = 0  # annotated frames that could not be read
    skipped_reasons: dict = field(default_factory=dict)  # of those, how many for what (not written)
    frames_unannotated: int = 0  # frames without annotations/<id>.png (not run)
    detections: int = 0
    ignored_instances: int = 0  # instances too small or of a class the detector does not know
    ignored_detections: int = 0  # detections that matched an ignored instance
    per_class: dict = field(default_factory=dict)  # class -> ClassStats
    confusion: dict = field(default_factory=dict)  # gt class | "background" -> {class | "missed": n}
    instances: list = field(default_factory=list)  # InstanceOutcome, counted or not
    warnings: list = field(default_factory=list)

    # -- overall figures --------------------------------------------------------------------------
    def _total(self) -> ClassStats:
        t = ClassStats()
        for s in self.per_class.values():
            t.instances += s.instances
            t.detected += s.detected
            t.tp += s.tp
            t.fp += s.fp
            t.fn += s.fn
            t.score_sum += s.score_sum
        return t

    @property
    def total(self) -> ClassStats:
        return self._total()

    @property
    def recall(self) -> float | None:
        return self._total().recall

    @property
    def precision(self) -> float | None:
        return self._total().precision

    @property
    def detection_rate(self) -> float | None:
        return self._total().detection_rate

    @property
    def v_other(self) -> float:
        rate = self.detection_rate
        if rate is None:
            raise CalibrationError("no ground-truth instance to measure the detector on", self.recording)
        return v_other_from_rate(rate)

    def class_v_other(self, name: str) -> float | None:
        s = self.per_class.get(name)
        overall = self.detection_rate
        if s is None or not s.instances or overall is None:
            return None
        return clip_v_other((s.detected + PRIOR_INSTANCES * overall) / (s.instances + PRIOR_INSTANCES))

    def to_document(self) -> dict:
        """The calibration file's content (``ltc-calibration/1``; schemas/calibration.schema.json)."""

        def rnd(v):
            return None if v is None else round(float(v), 4)

        t = self._total()
        per_class = {}
        for name in sorted(self.per_class):
            s = self.per_class[name]
            per_class[name] = {
                "instances": s.instances, "detected": s.detected, "tp": s.tp, "fp": s.fp, "fn": s.fn,
                "recall": rnd(s.recall), "precision": rnd(s.precision),
                "detection_rate": rnd(s.detection_rate), "mean_score": rnd(s.mean_score),
                "v_other": rnd(self.class_v_other(name)),
            }
        confusion = {k: dict(sorted(v.items())) for k, v in sorted(self.confusion.items())}
        return {
            "format": FORMAT,
            "ltc_version": __version__,
            "recording": self.recording,
            "recording_identity": self.recording_identity,
            "detector": self.detector,
            "detector_options": plain_options(self.detector_options),
            "frames": self.frames,
            "frames_skipped": self.frames_skipped,
            "frames_unannotated": self.frames_unannotated,
            "iou_threshold": float(self.iou_threshold),
            "min_pixels": int(self.min_pixels),
            "instances": t.instances,
            "ignored_instances": self.ignored_instances,
            "detections": self.detections,
            "tp": t.tp, "fp": t.fp, "fn": t.fn,
            "recall": rnd(t.recall),
            "precision": rnd(t.precision),
            "detection_rate": rnd(t.detection_rate),
            "mean_score": rnd(t.mean_score),
            "v_other": round(self.v_other, 4),
            "per_class": per_class,
            "confusion": confusion,
            "warnings": list(self.warnings),
            "method": METHOD,
        }


def plain_options(value):
    """Options as plain YAML types (paths and numpy scalars become str / float)."""
    if isinstance(value, dict):
        return {str(k): plain_options(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain_options(v) for v in value]
    if isinstance(value, (str, int, float, bool)) or value is None:
        return value
    if isinstance(value, np.generic):
        return value.item()
    return str(value)

def write_calibration(cal: Calibration | dict, path) -> dict:
    """Validate the calibration document and write it as YAML atomically (temporary file beside the
    target, fsync, ``os.replace``). Returns the document written."""
    doc = cal.to_document() if isinstance(cal, Calibration) else cal
    path = Path(path)
    validate(doc, "calibration", path)
    text = "# ltc calibration: the measured response of a detector (ltc calibrate); read by\n" \
           "# `ltc ingest --calibration`, which uses v_other. See docs/calibration.md.\n"
    text += yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, allow_unicode=True, width=110)
    try:
        write_text_atomic(path, text)
    except OSError as exc:
        raise LtcError(f"cannot write the calibration ({exc.strerror})", path) from None
    return doc


def load_calibration(path) -> dict:
    """Read and check a calibration file (schemas/calibration.schema.json)."""
    doc = read_yaml(path, "calibration")
    validate(doc, "calibration", path)
    return doc


def calibration_settings(doc: dict) -> dict:
    """The settings a calibration document gives an ingest: v_Other overall and per class. The
    response measured on annotated frames replaces the detection rate learnt from the map
    (``maintenance.learn_detection_rate`` off), which is the estimate for users who have none."""
    per_class = {
        name: float(stats["v_other"]) for name, stats in (doc.get("per_class") or {}).items()
        if isinstance(stats, dict) and stats.get("v_other") is not None
    }
    return {"maintenance": {"v_other": float(doc["v_other"]), "v_other_per_class": per_class,
                            "learn_detection_rate": False}}


__all__ = ["Calibration", "CalibrationError", "ClassStats", "InstanceOutcome", "FORMAT", "METHOD",
           "calibration_settings", "clip_v_other", "load_calibration", "plain_options",
           "v_other_from_rate", "write_calibration"]

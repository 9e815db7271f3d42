"""``ltc calibrate``: measure a detector's response on a recording with ground-truth instance masks,
and derive v_Other, the weight of ``other`` in a non-detection (eq. 4), from it.

What is measured
----------------
The detector runs over every frame that has a ground-truth instance image
(``annotations/<frame_id>.png``: uint16 object ids of the visible surface, 0 = none; the class of each
id comes from ``ground_truth.json``). In each frame, detections are matched to ground-truth instances
by mask IoU: every (detection, instance) pair with IoU >= ``iou_threshold`` (0.5) is a candidate, and
pairs are taken greedily by decreasing IoU, each detection and each instance at most once. Matching is
class-agnostic, so that a detection of the wrong class shows up in the confusion instead of as a miss
plus a false positive only.

Only instances that the mapper would hold against the detector count: at least ``min_pixels``
annotated (visible) pixels, the same idea as the maintenance setting
``maintenance.min_visible_pixels`` (1000 px at 640x480, scaled with the image area, so 250 px at
320x240), and a class that is in the detector's vocabulary (a detector cannot be blamed for a class it
does not know). Smaller or out-of-vocabulary instances are *ignored*: they are not misses, and a
detection that matches one is not a false positive either.

Counts, per ground-truth class c and overall:

- TP: an instance of class c matched by a detection whose top class is c;
- FN: an instance of class c that is unmatched ("missed"), or matched with another top class;
- FP: a detection of class c that matches no instance (row ``background`` of the confusion), or that
  matches an instance of another class;
- recall = TP / (TP + FN), precision = TP / (TP + FP) (class-aware, the usual definitions);
- detection rate = (instances matched by any detection) / (instances) (class-agnostic);
- confusion[c][d]: instances of class c matched by a detection of top class d; confusion[c]["missed"]:
  instances of class c that no detection matched; confusion["background"][d]: unmatched detections.

How v_Other is derived, and why
-------------------------------
Map maintenance (DESIGN.md 1.4) gives a map object that should have been seen (in view, in range,
enough visible pixels) and that matched no detection a *non-detection*: the class vector of eq. 4,
``other`` = v_Other and (1 - v_Other) / r on each of the r classes, fused by eq. 3 like a detection.
So a non-detection is a vote of weight v_Other for "this object is gone", exactly as a detection is a
vote of weight s (its score) for its class.

How much such a vote should weigh depends on how reliable the detector is on objects that are there
and visible enough. Let R = P(some detection matches the object | it is present and visible enough),
the class-agnostic detection rate measured above on exactly that population (enough visible pixels; a
detection of another class still associates with the map object, so it is not a non-detection). If
the object is present, a non-detection happens with probability 1 - R; if it is gone, always. A
detector with R close to 1 almost never misses a present object, so its silence is almost conclusive:
v_Other should be close to 1. A detector with R close to 0 misses present objects all the time, so its
silence says almost nothing: v_Other should be close to 0, and the non-detection vector is then nearly
uniform over the classes (it lowers the confidence of the current class without voting for removal).
We take the natural interpolation:

    v_Other = R, clipped to [0.05, 0.95]

i.e. a non-detection says "gone" with the probability that this detector would have seen the object
had it been there. The clip keeps both a perfect detector (one unlucky miss never removes an object
outright) and a useless one (v_Other = 0 would make eq. 4 unable to ever remove anything) usable.

Why this keeps present objects and removes absent ones. Fused by eq. 3 (a running mean, or with
``integration.max_weight`` an exponential average), a present object of class c seen repeatedly sees a
fraction R of detections (mean score q for c) and 1 - R of non-detections; its expected vector has
``other`` = (1 - R) v_Other and class c = R q + (1 - R)(1 - v_Other)/r. With v_Other = R, ``other``
stays below c as long as (1 - R) R < R q, i.e. 1 - R < q: whenever the detector misses less often than
its typical score, which holds for any usable detector (the calibration warns when it does not). A
removed object only gets non-detections, so ``other`` climbs towards v_Other = R while c decays
towards (1 - R)/r: it is removed, and the higher the recall the fewer non-detections it takes (with
the default weight cap of 5 and q = 0.9: about 4 non-detections at R = 0.9, 9 at R = 0.3). The
paper's fixed 0.5 corresponds to a detector that finds half of the visible objects.

Per class, the same rule uses the class's detection rate, shrunk towards the overall one so that a
class with a handful of instances does not get an extreme value: v_c = (detected_c + k R) /
(instances_c + k) with k = 10 (a Beta prior worth ten instances centred on the overall rate), then
clipped. ``ltc ingest --calibration`` uses both: the per-class value for objects of a class measured
here, the overall one for the others.

The calibration document itself (reading, writing, the settings it gives an ingest) is in
ltc_cli/tools/calibration_file.py.
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np
from PIL import Image

from ltc_cli import plugins
from ltc_cli.errors import FrameError, RecordingError
from ltc_cli.text import SkippedFrames
from ltc_cli.tools.calibration_file import (
    METHOD, Calibration, CalibrationError, ClassStats, InstanceOutcome, v_other_from_rate, write_calibration,
)

#: The reference image area of ``maintenance.min_visible_pixels`` (DESIGN.md: 1000 px at 640x480).
REFERENCE_AREA = 640 * 480
BACKGROUND = "background"
MISSED = "missed"


def scaled_min_pixels(min_visible_pixels: float, width: int, height: int) -> int:
    """``maintenance.min_visible_pixels`` (given at 640x480) for a width x height image."""
    return max(1, int(round(float(min_visible_pixels) * width * height / REFERENCE_AREA)))


def read_annotation(path: Path, shape: tuple[int, int]) -> np.ndarray:
    """The ground-truth instance image (H, W) of object ids (0 = none); FrameError when unusable."""
    try:
        with Image.open(path) as im:
            ids = np.asarray(im)
    except (OSError, ValueError) as exc:
        raise FrameError(f"cannot read the annotation ({exc})", path) from None
    if ids.ndim != 2 or ids.dtype.kind not in "ui":
        raise FrameError("annotation must be a single-channel integer PNG of object ids", path)
    if ids.shape != tuple(shape):
        raise FrameError(f"annotation is {ids.shape[1]}x{ids.shape[0]}, frame is {shape[1]}x{shape[0]}", path)
    if ids.min() < 0:
        raise FrameError("annotation has negative ids", path)
    return ids.astype(np.int64, copy=False)


def match_frame(ids: np.ndarray, masks: list[np.ndarray], iou_threshold: float):
    """Greedy IoU matching of detection masks to the instances of ``ids`` (H, W).

    Returns (gt_ids (G,), gt_pixels (G,), pairs) with pairs a list of (detection index, gt index,
    IoU), each detection and each instance at most once, taken by decreasing IoU (ties: lower
    detection index, then lower id).
    """
    original = None
    if ids.size and int(ids.max()) > 65535:  # large ids: relabel 0..n so that bincount stays small
        original, inv = np.unique(ids, return_inverse=True)
        if original[0] != 0:
            original, inv = np.r_[0, original], inv + 1
        ids = inv.reshape(ids.shape)
    counts = np.bincount(ids.ravel())
    gt_ids = np.flatnonzero(counts)
    gt_ids = gt_ids[gt_ids > 0]
    gt_pixels = counts[gt_ids]
    pos = np.full(counts.size, -1, dtype=np.int64)
    pos[gt_ids] = np.arange(gt_ids.size)
    cand = []
    for d, mask in enumerate(masks):
        area = int(mask.sum())
        if area == 0 or gt_ids.size == 0:
            continue
        inter = np.bincount(ids[mask], minlength=counts.size)
        hit = np.flatnonzero(inter)
        hit = hit[hit > 0]
        for oid in hit:
            i = int(inter[oid])
            iou = i / (area + int(counts[oid]) - i)
            if iou >= iou_threshold:
                cand.append((-iou, d, int(oid)))
    cand.sort()
    used_d, used_g, pairs = set(), set(), []
    for neg_iou, d, oid in cand:
        if d in used_d or oid in used_g:
            continue
        used_d.add(d)
        used_g.add(oid)
        pairs.append((d, int(pos[oid]), -neg_iou))
    if original is not None:
        gt_ids = original[gt_ids]
    return gt_ids, gt_pixels, pairs


def calibrate(
    recording_path,
    detector: str = "recorded",
    detector_options: dict | None = None,
    *,
    reader: str | None = None,
    reader_options: dict | None = None,
    min_visible_pixels: float = 1000,
    min_pixels: int | None = None,
    iou_threshold: float = 0.5,
    progress: Callable | None = None,
    warn: Callable[[str], None] | None = None,
) -> Calibration:
    """Run ``detector`` over the annotated frames of a recording and measure its response.

    min_visible_pixels: the instance size that counts, in pixels at 640x480 (scaled with the image
        area, like ``maintenance.min_visible_pixels``); ``min_pixels`` gives it in pixels of this
        recording's images instead.
    progress: called with 1 after each frame (annotated or not); warn: called with a message for each
        frame skipped (unreadable frame, annotation or detections).

    Raises RecordingError when the recording has no annotations/ folder or no ground_truth.json,
    CalibrationError when no frame could be evaluated or no instance counts.
    """
    from ltc_cli.recordings.groundtruth import read_ground_truth
    from ltc_cli.recordings.open import open_recording

    warn = warn or (lambda msg: None)
    if not 0.0 < float(iou_threshold) <= 1.0:
        raise CalibrationError(f"the IoU threshold must be in (0, 1], not {iou_threshold}")
    rec = open_recording(recording_path, reader, reader_options)
    root = Path(rec.path)
    ann_dir = root / "annotations"
    if not ann_dir.is_dir():
        raise RecordingError("no annotations/ folder: calibrate needs ground-truth instance masks", root)
    gt_path = root / "ground_truth.json"
    if not gt_path.is_file():
        raise RecordingError("no ground_truth.json: calibrate needs the class of each annotated object id", root)
    gt = read_ground_truth(gt_path)
    class_of = {int(o["id"]): str(o["class"]) for o in gt["objects"]}

    options = dict(detector_options or {})
    det = plugins.get("detectors", detector).factory(rec, dict(options))
    vocab = list(det.classes)
    known = set(vocab)
    W, H = rec.intrinsics.width, rec.intrinsics.height
    if min_pixels is None:
        min_pixels = scaled_min_pixels(min_visible_pixels, W, H)
    min_pixels = int(min_pixels)
    if min_pixels < 1:
        raise CalibrationError(f"min_pixels must be at least 1, not {min_pixels}")

    cal = Calibration(
        recording=str(root.resolve()), recording_identity=rec.identity, detector=detector,
        detector_options=options, classes=vocab, min_pixels=min_pixels, iou_threshold=float(iou_threshold),
    )
    unknown_ids: set = set()

    def stats(name: str) -> ClassStats:
        return cal.per_class.setdefault(name, ClassStats())

    def confuse(row: str, col: str) -> None:
        r = cal.confusion.setdefault(row, {})
        r[col] = r.get(col, 0) + 1

    skips = SkippedFrames(warn)
    for ref in rec.frames:
        ann_path = ann_dir / f"{ref.key}.png"
        if not ann_path.is_file():
            cal.frames_unannotated += 1
            if progress:
                progress(1)
            continue
        try:
            frame = ref.load()
            ids = read_annotation(ann_path, frame.depth_m.shape)
            dets = det.detect(frame)
        except FrameError as exc:
            skips.skip(ref.key, exc)
            cal.frames_skipped += 1
            if progress:
                progress(1)
            continue
        masks = [np.asarray(d.mask, dtype=bool) for d in dets]
        det_cls = [vocab[int(np.argmax(d.scores))] for d in dets]
        gt_ids, gt_px, pairs = match_frame(ids, masks, iou_threshold)
        match_of_gt = {g: (d, iou) for d, g, iou in pairs}
        matched_dets = set()
        for g, (oid, npx) in enumerate(zip(gt_ids.tolist(), gt_px.tolist())):
            name = class_of.get(oid)
            if name is None and oid not in unknown_ids:
                unknown_ids.add(oid)
                warn(f"object id {oid} of {ann_path} is not in {gt_path}: ignored")
            counted = name is not None and name in known and npx >= min_pixels
            d, iou = match_of_gt.get(g, (None, 0.0))
            got = det_cls[d] if d is not None else None
            score = 0.0
            if d is not None and name in known:
                score = float(np.asarray(dets[d].scores)[vocab.index(name)])
            cal.instances.append(InstanceOutcome(ref.key, oid, name or "", npx, counted, got, float(iou), score))
            if not counted:
                cal.ignored_instances += 1
                if d is not None:
                    cal.ignored_detections += 1
                    matched_dets.add(d)
                continue
            s = stats(name)
            s.instances += 1
            if d is None:
                s.fn += 1
                confuse(name, MISSED)
                continue
            matched_dets.add(d)
            s.detected += 1
            s.score_sum += score
            confuse(name, got)
            if got == name:
                s.tp += 1
            else:
                s.fn += 1
                stats(got).fp += 1
        for d, name in enumerate(det_cls):
            if d not in matched_dets:
                stats(name).fp += 1
                confuse(BACKGROUND, name)
        cal.detections += len(dets)
        cal.frames += 1
        if progress:
            progress(1)

    if cal.frames == 0:
        raise CalibrationError(
            "no frame could be evaluated (no annotations/<frame_id>.png for the recording's frames, "
            "or none readable)", root)
    total = cal.total
    if total.instances == 0:
        raise CalibrationError(
            f"no ground-truth instance with at least {min_pixels} visible pixels of a class the detector "
            f"knows, in {cal.frames} frames: nothing to measure", root)
    _stability_warnings(cal)
    cal.skipped_reasons = dict(skips.counts)
    return cal


def _stability_warnings(cal: Calibration) -> None:
    """Warn when eq. 3 would be expected to remove objects that are present (module docstring)."""
    t = cal.total
    R = t.detection_rate
    q = t.mean_score
    if R is None:
        return
    v = cal.v_other
    r = max(1, len(cal.classes))
    q = q or 0.0
    expected_other = (1 - R) * v
    expected_class = R * q + (1 - R) * (1 - v) / r
    if expected_other >= expected_class:
        cal.warnings.append(
            f"detection rate {R:.2f} with mean score {q:.2f}: non-detections of present objects are "
            f"expected to outweigh their detections, so maintenance would remove objects that are there; "
            f"use a better detector, or give a lower v_other")
    if t.instances < 100:
        cal.warnings.append(f"only {t.instances} instances measured: v_other is uncertain "
                            f"(standard error {np.sqrt(max(R * (1 - R), 0.01) / t.instances):.2f})")


__all__ = ["calibrate", "write_calibration", "Calibration", "ClassStats", "InstanceOutcome",
           "CalibrationError", "match_frame", "scaled_min_pixels", "v_other_from_rate", "METHOD"]

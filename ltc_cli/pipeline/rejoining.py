"""Stage 4 across sessions: at a session's end, which new objects are an earlier one seen again.

A robot's localiser is off by a few centimetres, in another way on each drive, and a detector names
some things only once per visit: a thing seen again in a later session may get a box of its own
beside its first one, or confirm one removed before. These rules pair such objects (pure numpy);
:class:`~ltc_cli.pipeline.pruning.SessionPruning` joins them and logs it. DESIGN.md 1.4, and
docs/decisions.md (issue 9).
"""

from __future__ import annotations

import numpy as np

from ltc_cli.geometry.boxes import Boxes
from ltc_cli.geometry.polygons import pairwise_ious_arrays
from ltc_cli.pipeline.association import footprint_gaps


def same_class_overlap(boxes: Boxes, top: np.ndarray, earlier: Boxes, earlier_top: np.ndarray) -> np.ndarray:
    """(K,) index into ``earlier`` of the object of the same top class whose footprint overlaps
    that of each of K objects (``boxes``, ``top`` (K,)) the most, or -1. For confirm_across_sessions:
    ``earlier`` an earlier session's unconfirmed objects (the thing seen before), or the map's
    active ones (the thing already mapped).

    The confirmation rule asks two detections from two views of one session, against a detector's
    one-off false positives. A thing the detector names once per visit (a tv seen at an angle, a
    table half hidden by chairs) is removed at every session's end; named again at the same place
    in a later session, from a view a session apart, it is the same evidence twice."""
    out = np.full(len(boxes), -1, dtype=int)
    if not len(boxes) or not len(earlier):
        return out
    iou, _ = pairwise_ious_arrays(boxes.center, boxes.yaw, boxes.size, earlier.center, earlier.yaw, earlier.size)
    ok = (iou > 0.0) & (np.asarray(top)[:, None] == np.asarray(earlier_top)[None, :])
    best = np.where(ok, iou, -1.0).argmax(axis=1)
    return np.where(ok.any(axis=1), best, -1)


def drifted_match(boxes: Boxes, top: np.ndarray, earlier: Boxes, earlier_top: np.ndarray, others: Boxes,
                  others_top: np.ndarray, margin: float) -> np.ndarray:
    """(K,) index into ``earlier`` of the object of the same top class whose footprint lies within
    ``margin`` metres of that of each of K objects (``boxes``, ``top`` (K,)), the nearest, or -1;
    also -1 where one of ``others`` of that class lies nearer still.

    For ``maintenance.reidentify_margin``: ``boxes`` this session's confirmed new objects,
    ``earlier`` the objects the absence rule is about to remove (seen clearly in this session and
    never detected), ``others`` the rest of the active map. A robot's localiser is off by a few centimetres, in
    another way on each drive: a thing a few centimetres wide that the second drive sees beside
    the box the first gave it is a new box there, and its old box, seen empty where it stands, goes
    (tum-fr1-rpy with a localiser's drift: a game controller 11 cm from its old box lost its id).
    A thing detected in this session nearer to the new one is what it stands beside."""
    out = np.full(len(boxes), -1, dtype=int)
    if not len(boxes) or not len(earlier):
        return out
    for k in range(len(boxes)):
        one = boxes.take(slice(k, k + 1))
        gaps = np.where(np.asarray(earlier_top) == top[k], footprint_gaps(one, earlier), np.inf)
        best = int(np.argmin(gaps))
        if gaps[best] > margin:
            continue
        rivals = np.asarray(others_top) == top[k]
        if rivals.any() and (footprint_gaps(one, others.take(np.flatnonzero(rivals))) < gaps[best]).any():
            continue
        out[k] = best
    return out


def earlier_duplicates(boxes: Boxes, top: np.ndarray, earlier: Boxes, earlier_top: np.ndarray,
                       min_iou, same: bool = False) -> list[tuple[int, int, float]]:
    """[(k, j, iou)]: each of K objects (``boxes``, ``top`` (K,)) paired with the object of ``earlier``
    of its top class whose footprint it overlaps by an XY IoU of at least ``min_iou`` (one bar, or
    (K, J) one per pair), greatest overlaps first, each object in at most one pair.

    For ``maintenance.earlier_overlap_iou``: ``boxes`` this session's confirmed new objects,
    ``earlier`` the active objects of earlier sessions. Two boxes of one class that share that
    much ground are one thing seen in two drives, off by the localiser's drift between them (on
    tum-fr1-rpy with a drift: the trackball and the game controller again 7-11 cm from their first
    boxes, IoU 0.18-0.35). The merges within a frame do not join them: a small thing's drifted copy
    lies beyond eq. 2's size cap (``same_class_scale``) and the two together beyond
    ``max_union_length``. Two things of one class side by side share next to none (on tum-fr1-rpy
    the second chair, which a drive's other half adds beside the first: 0.01).

    ``same``: ``earlier`` is ``boxes`` itself, ordered best seen first (``session_overlap_iou``):
    each pair once, the later object (k) into the earlier (j < k), each object in one pair."""
    if not len(boxes) or not len(earlier):
        return []
    iou, _ = pairwise_ious_arrays(boxes.center, boxes.yaw, boxes.size, earlier.center, earlier.yaw, earlier.size)
    ok = (np.asarray(top)[:, None] == np.asarray(earlier_top)[None, :]) & (iou >= min_iou) & (iou > 0.0)
    iou = np.where(ok, iou, -1.0)
    if same:
        iou[np.triu_indices(len(boxes))] = -1.0
    pairs, used_k, used_j = [], set(), set()
    for flat in np.argsort(-iou, axis=None, kind="stable"):
        k, j = (int(v) for v in np.unravel_index(flat, iou.shape))
        if iou[k, j] <= 0.0:
            break
        if k not in used_k and j not in used_j and not (same and (k in used_j or j in used_k)):
            pairs.append((k, j, float(iou[k, j])))
            used_k.add(k)
            used_j.add(j)
    return pairs


def join_bars(size_new: np.ndarray, size_old: np.ndarray, min_iou: float, small_iou: float | None,
              small_width: float) -> np.ndarray:
    """(K, J) the XY IoU that joins each of K new objects (sizes (K, 3)) with each of J earlier ones:
    ``small_iou`` when both are small (longer side at most ``small_width``; None: ``min_iou``).

    A revisit's drift moves a small thing's views by much of its size (tum-fr1-rpy: the white
    mouse, 0.14 m, 0.1 m off its first box, IoU 0.095; the trackball's new box IoU 0.03 with its
    old one), where a chair's drifted copy still shares most of its ground."""
    bars = np.full((len(size_new), len(size_old)), float(min_iou))
    if small_iou is not None:
        bars[small_things(size_new, small_width)[:, None] & small_things(size_old, small_width)[None, :]] = small_iou
    return bars


def small_things(size: np.ndarray, width: float) -> np.ndarray:
    """(M,) bool: boxes (sizes (M, 3)) whose longer footprint side is at most ``width`` metres."""
    return np.asarray(size)[:, :2].max(axis=1) <= width

"""Compare map objects with ground-truth objects (DESIGN.md section 8; the paper's Tables 1-2).

Pure numpy, no I/O. Boxes follow DESIGN.md section 2: ``center (3,)``, ``yaw`` about z, ``size (3,)``
along the box's own x, y and the world z.

Overlap measures are exact for Z-oriented boxes:

- XY IoU: the two footprints are rectangles; their intersection is a convex polygon of at most 8
  vertices, computed by Sutherland-Hodgman clipping (vectorised over many box pairs at once) and
  measured with the shoelace formula.
- VIoU: footprint intersection area times the overlap of the z intervals, over the union volume
  (two Z-oriented boxes intersect in a prism: a convex footprint polygon extruded along z).

Matching (:func:`evaluate`): one-to-one, same class only, among pairs with XY IoU > 0 and centres within
``max_center_distance``; greedy by descending XY IoU (ties: smaller centre distance, then input
order). Greedy is what the paper's evaluation does in spirit and is stable; an optimal (Hungarian)
assignment differs only when one object overlaps several of the same class, which is rare in a map
that is supposed to be one-to-one with the furniture.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ltc_cli.errors import LtcError
from ltc_cli.geometry.polygons import pairwise_ious_arrays
from ltc_cli.map.model import SemanticMap


class EvaluationError(LtcError):
    """Inputs to the evaluation that cannot be compared (malformed boxes or objects)."""


# ---------------------------------------------------------------------------------------------
# Objects


@dataclass
class EvalObject:
    """One object to compare: a map object or a ground-truth object.

    ``center (3,)``, ``yaw`` (radians), ``size (3,)`` in the map frame; ``seen_pixels`` only for
    ground truth (None = unknown, treated as seen).
    """

    id: int
    cls: str
    center: np.ndarray
    yaw: float
    size: np.ndarray
    seen_pixels: int | None = None
    extra: dict = field(default_factory=dict)


_CLASS_KEYS = ("class", "cls", "class_name", "label")


def _get(obj, key, default=None):
    if isinstance(obj, Mapping):
        return obj.get(key, default)
    return getattr(obj, key, default)


def as_eval_object(obj) -> EvalObject:
    """An :class:`EvalObject` from a dict (keys id, class, center, yaw, size[, seen_pixels]) or any
    object with those attributes (the class as ``cls``, ``class_name`` or ``label``)."""
    if isinstance(obj, EvalObject):
        return obj
    cls = None
    for key in _CLASS_KEYS:
        cls = _get(obj, key)
        if cls is not None:
            break
    oid = _get(obj, "id")
    center, yaw, size = _get(obj, "center"), _get(obj, "yaw"), _get(obj, "size")
    if cls is None or oid is None or center is None or yaw is None or size is None:
        raise EvaluationError(
            f"object {obj!r:.80} lacks one of id, class, center, yaw, size"
        )
    center = np.asarray(center, dtype=np.float64).reshape(-1)
    size = np.asarray(size, dtype=np.float64).reshape(-1)
    if center.shape != (3,) or size.shape != (3,):
        raise EvaluationError(f"object {oid}: center and size must have 3 values")
    yaw = float(yaw)
    if not (np.all(np.isfinite(center)) and np.all(np.isfinite(size)) and np.isfinite(yaw)):
        raise EvaluationError(f"object {oid}: non-finite box")
    if np.any(size < 0):
        raise EvaluationError(f"object {oid}: negative size")
    seen = _get(obj, "seen_pixels")
    return EvalObject(int(oid), str(cls), center, yaw, size, None if seen is None else int(seen))


def _box_tuple(box):
    """(center (3,), yaw, size (3,)) of a box given as a dict / object / (center, yaw, size)."""
    if isinstance(box, (tuple, list)) and len(box) == 3 and np.ndim(box[1]) == 0:
        center, yaw, size = box
    else:
        center, yaw, size = _get(box, "center"), _get(box, "yaw"), _get(box, "size")
        if center is None or yaw is None or size is None:
            raise EvaluationError(f"not a box: {box!r:.80}")
    center = np.asarray(center, dtype=np.float64).reshape(3)
    size = np.asarray(size, dtype=np.float64).reshape(3)
    return center, float(yaw), size


def _box_arrays(boxes):
    """center (N, 3), yaw (N,), size (N, 3) of a sequence of boxes or an object with array fields
    (e.g. :class:`ltc_cli.geometry.Boxes`)."""
    if hasattr(boxes, "center") and hasattr(boxes, "yaw") and np.ndim(_get(boxes, "yaw")) == 1:
        return (
            np.asarray(boxes.center, dtype=np.float64).reshape(-1, 3),
            np.asarray(boxes.yaw, dtype=np.float64).reshape(-1),
            np.asarray(boxes.size, dtype=np.float64).reshape(-1, 3),
        )
    tuples = [_box_tuple(b) for b in boxes]
    if not tuples:
        return np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3))
    c, y, s = zip(*tuples)
    return np.array(c), np.array(y), np.array(s)


# ---------------------------------------------------------------------------------------------
# Exact convex polygon intersection (vectorised Sutherland-Hodgman)


# ---------------------------------------------------------------------------------------------
# IoU of Z-oriented boxes


def pairwise_ious(boxes_a, boxes_b):
    """(xy_iou (M, G), viou (M, G)) of two collections of boxes.

    Each collection is a sequence of boxes (dicts / objects with center, yaw, size, or
    ``(center, yaw, size)`` tuples) or an object with array fields ``center (N, 3)``, ``yaw (N,)``,
    ``size (N, 3)`` such as :class:`ltc_cli.geometry.Boxes`.
    """
    return pairwise_ious_arrays(*_box_arrays(boxes_a), *_box_arrays(boxes_b))


def xy_iou(box_a, box_b) -> float:
    """Exact IoU of the XY footprints of two Z-oriented boxes (dicts, objects or
    ``(center (3,), yaw, size (3,))`` tuples)."""
    ca, ya, sa = _box_tuple(box_a)
    cb, yb, sb = _box_tuple(box_b)
    return float(pairwise_ious_arrays(ca, [ya], sa, cb, [yb], sb)[0][0, 0])


def volume_iou(box_a, box_b) -> float:
    """Exact 3D IoU (VIoU) of two Z-oriented boxes: footprint intersection x z overlap / union."""
    ca, ya, sa = _box_tuple(box_a)
    cb, yb, sb = _box_tuple(box_b)
    return float(pairwise_ious_arrays(ca, [ya], sa, cb, [yb], sb)[1][0, 0])


# ---------------------------------------------------------------------------------------------
# Matching and metrics


def _prf(tp: int, fp: int, fn: int):
    """precision, recall, F1; 0.0 when a denominator is 0 (scikit-learn's zero_division=0)."""
    precision = tp / (tp + fp) if tp + fp else 0.0
    recall = tp / (tp + fn) if tp + fn else 0.0
    f1 = 2 * precision * recall / (precision + recall) if precision + recall else 0.0
    return precision, recall, f1


def _mean(values):
    """Mean of a list, None when empty (no TP: the figure does not exist)."""
    return float(np.mean(values)) if len(values) else None


def _objects_and_changes(gt):
    """(objects, changes | None) from a list of objects or a ground_truth.json-like dict."""
    if gt is None:
        return [], None
    if isinstance(gt, Mapping) and "objects" in gt:
        return [as_eval_object(o) for o in gt["objects"]], gt.get("changes")
    return [as_eval_object(o) for o in gt], None


def _infer_changes(current, previous):
    """moved and removed ids of ``previous`` relative to ``current`` when no changes are given."""
    now = {o.id: o for o in current}
    moved, removed = [], []
    for o in previous:
        c = now.get(o.id)
        if c is None:
            removed.append(o.id)
        elif (
            np.abs(c.center - o.center).max() > 1e-6
            or np.abs(c.size - o.size).max() > 1e-6
            or abs(c.yaw - o.yaw) > 1e-6
        ):
            moved.append(o.id)
    return {"moved": moved, "removed": removed, "added": sorted(set(now) - {o.id for o in previous})}


def evaluate(
    map_objects,
    gt_objects,
    *,
    max_center_distance: float = 3.0,
    seen_only: bool = False,
    min_seen_pixels: int = 1,
    previous_gt=None,
    changes=None,
) -> dict:
    """Compare a map with the ground truth.

    map_objects: sequence of objects (dicts or objects with id, class, center, yaw, size; see
        :func:`as_eval_object`).
    gt_objects: sequence of ground-truth objects, or a ground_truth.json dict (then its
        ``changes`` are used unless ``changes`` is given).
    max_center_distance: metres; a match also needs the 3D distance between the centres (which is
        also the reported position error) to be at most this.
    seen_only: ground-truth objects with ``seen_pixels < min_seen_pixels`` (the robot never saw
        them) that are not matched are ignored instead of counted as FN. One that *is* matched stays
        a TP (the map object is right), so recall = TP / (TP + FN) stays within [0, 1].
    previous_gt: the earlier lap's objects (sequence or ground_truth dict) for counting ghosts.
    changes: {"moved": [...], "removed": [...]} ids; default: those of ``gt_objects`` when it is a
        dict with changes, else inferred by comparing ``previous_gt`` with ``gt_objects``.

    Every map object that is not a TP is an FP, and falls in exactly one of:
      - ``ghost``: same class and XY IoU > 0 with the previous-lap box of a removed or moved
        object, at least as much as with any matched current ground-truth object of its class (the
        map still shows the object where it used to be);
      - ``duplicate``: its best same-class ground-truth candidate (XY IoU > 0, centre within
        ``max_center_distance``) was matched by another map object (a second instance of it);
      - otherwise a plain false positive.

    Returns a dict: tp, fp, fn, num_map, num_gt, ignored_gt, precision, recall, f1, mean_xy_iou,
    mean_viou, mean_position_error (over the TPs; None without TP), duplicates, ghosts,
    duplicate_ratio, ghost_ratio (over num_map), matches [{map_id, gt_id, class, xy_iou, viou,
    position_error}], fp_ids, fn_ids, duplicate_ids, ghost_ids, ignored_gt_ids and per_class
    {class: {num_map, num_gt, tp, fp, fn, precision, recall, f1, mean_xy_iou, mean_viou,
    mean_position_error, duplicates, ghosts}}.
    """
    if not max_center_distance > 0:
        raise EvaluationError(f"max_center_distance must be > 0, not {max_center_distance}")
    maps = [as_eval_object(o) for o in map_objects]
    gts, gt_changes = _objects_and_changes(gt_objects)
    prev, _ = _objects_and_changes(previous_gt)
    if changes is None:
        changes = gt_changes
    if changes is None and previous_gt is not None:
        changes = _infer_changes(gts, prev)
    M, G = len(maps), len(gts)

    def arrays(objs):
        if not objs:
            return np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3))
        return (
            np.array([o.center for o in objs]),
            np.array([o.yaw for o in objs]),
            np.array([o.size for o in objs]),
        )

    ca, ya, sa = arrays(maps)
    cg, yg, sg = arrays(gts)
    iou, viou = pairwise_ious_arrays(ca, ya, sa, cg, yg, sg)
    dist = (
        np.linalg.norm(ca[:, None, :] - cg[None, :, :], axis=2) if M and G else np.zeros((M, G))
    )
    same = np.array([[m.cls == g.cls for g in gts] for m in maps], dtype=bool).reshape(M, G)
    cand = same & (iou > 0) & (dist <= max_center_distance)

    # Greedy one-to-one matching by descending IoU (ties: nearer centres, then input order).
    mi, gi = np.nonzero(cand)
    order = np.lexsort((gi, mi, dist[mi, gi], -iou[mi, gi]))
    map_match = np.full(M, -1)
    gt_match = np.full(G, -1)
    for k in order:
        i, j = mi[k], gi[k]
        if map_match[i] < 0 and gt_match[j] < 0:
            map_match[i], gt_match[j] = j, i

    unseen = np.array(
        [g.seen_pixels is not None and g.seen_pixels < min_seen_pixels for g in gts], dtype=bool
    )
    ignored = (gt_match < 0) & unseen if seen_only else np.zeros(G, dtype=bool)

    # Former places of removed / moved objects (previous-lap boxes) for ghosts.
    former = []
    if changes and prev:
        gone = set(int(x) for x in changes.get("removed", [])) | set(
            int(x) for x in changes.get("moved", [])
        )
        former = [o for o in prev if o.id in gone]
    if former and M:
        iou_prev, _ = pairwise_ious_arrays(ca, ya, sa, *arrays(former))
        same_prev = np.array([[m.cls == f.cls for f in former] for m in maps], dtype=bool)
        ghost_iou = np.where(same_prev, iou_prev, 0.0).max(axis=1)
    else:
        ghost_iou = np.zeros(M)

    kind = np.array(["tp"] * M, dtype=object)
    matched_gt = gt_match >= 0
    for i in range(M):
        if map_match[i] >= 0:
            continue
        row = np.where(cand[i], iou[i], 0.0)
        best_matched = float(np.where(matched_gt, np.where(same[i], iou[i], 0.0), 0.0).max(initial=0))
        if ghost_iou[i] > 0 and ghost_iou[i] >= best_matched:
            kind[i] = "ghost"
        elif row.max(initial=0) > 0 and matched_gt[int(np.argmax(row))]:
            kind[i] = "duplicate"
        else:
            kind[i] = "fp"

    matches = []
    for i in range(M):
        j = map_match[i]
        if j >= 0:
            matches.append(
                {
                    "map_id": maps[i].id,
                    "gt_id": gts[j].id,
                    "class": maps[i].cls,
                    "xy_iou": float(iou[i, j]),
                    "viou": float(viou[i, j]),
                    "position_error": float(dist[i, j]),
                }
            )

    def summary(map_sel, gt_sel):
        tp = int(sum(1 for i in np.flatnonzero(map_sel) if map_match[i] >= 0))
        fp = int(map_sel.sum()) - tp
        fn = int(sum(1 for j in np.flatnonzero(gt_sel) if gt_match[j] < 0 and not ignored[j]))
        p, r, f1 = _prf(tp, fp, fn)
        tps = [i for i in np.flatnonzero(map_sel) if map_match[i] >= 0]
        dup = int(sum(1 for i in np.flatnonzero(map_sel) if kind[i] == "duplicate"))
        gho = int(sum(1 for i in np.flatnonzero(map_sel) if kind[i] == "ghost"))
        return {
            "num_map": int(map_sel.sum()),
            "num_gt": int(gt_sel.sum()),
            "tp": tp,
            "fp": fp,
            "fn": fn,
            "precision": p,
            "recall": r,
            "f1": f1,
            "mean_xy_iou": _mean([iou[i, map_match[i]] for i in tps]),
            "mean_viou": _mean([viou[i, map_match[i]] for i in tps]),
            "mean_position_error": _mean([dist[i, map_match[i]] for i in tps]),
            "duplicates": dup,
            "ghosts": gho,
        }

    result = summary(np.ones(M, dtype=bool), np.ones(G, dtype=bool))
    result["ignored_gt"] = int(ignored.sum())
    result["duplicate_ratio"] = result["duplicates"] / M if M else 0.0
    result["ghost_ratio"] = result["ghosts"] / M if M else 0.0
    result["matches"] = matches
    result["fp_ids"] = [maps[i].id for i in range(M) if map_match[i] < 0]
    result["fn_ids"] = [gts[j].id for j in range(G) if gt_match[j] < 0 and not ignored[j]]
    result["duplicate_ids"] = [maps[i].id for i in range(M) if kind[i] == "duplicate"]
    result["ghost_ids"] = [maps[i].id for i in range(M) if kind[i] == "ghost"]
    result["ignored_gt_ids"] = [gts[j].id for j in range(G) if ignored[j]]
    classes = sorted({m.cls for m in maps} | {g.cls for g in gts})
    map_cls = np.array([m.cls for m in maps], dtype=object)
    gt_cls = np.array([g.cls for g in gts], dtype=object)
    result["per_class"] = {c: summary(map_cls == c, gt_cls == c) for c in classes}
    return result


def map_objects(smap: SemanticMap) -> list[dict]:
    """The active objects of a map as {id, class, center, yaw, size} (class = top non-other score)."""
    t = smap.objects
    rows = smap.active_rows()
    top = t.scores[rows, :-1].argmax(axis=1) if len(rows) else np.zeros(0, int)
    return [
        {"id": int(r + 1), "class": smap.classes[int(c)], "center": t.center[r], "yaw": float(t.yaw[r]),
         "size": t.size[r]}
        for r, c in zip(rows, top)
    ]


def evaluate_map(smap: SemanticMap, gt: dict, previous: dict | None = None, **kw) -> dict:
    """Metrics of DESIGN.md section 8 for a map, with recall over all ground-truth objects and
    over those the robot saw (``recall_seen``)."""
    objs = map_objects(smap)
    res = evaluate(objs, gt, previous_gt=previous, **kw)
    seen = evaluate(objs, gt, previous_gt=previous, seen_only=True, **kw)
    res["recall_seen"] = seen["recall"]
    res["f1_seen"] = seen["f1"]
    return res

"""Compare map objects with ground-truth objects (DESIGN.md section 8; the paper's Tables 1-2).

Pure numpy, no I/O. Boxes follow DESIGN.md section 2: ``center (3,)``, ``yaw`` about z, ``size (3,)``
along the box's own x, y and the world z.

Overlap measures are exact for Z-oriented boxes (:mod:`ltc_cli.tools.eval_objects`):

- XY IoU: the two footprints are rectangles; their intersection is a convex polygon of at most 8
  vertices, computed by Sutherland-Hodgman clipping (vectorised over many box pairs at once) and
  measured with the shoelace formula.
- VIoU: footprint intersection area times the overlap of the z intervals, over the union volume
  (two Z-oriented boxes intersect in a prism: a convex footprint polygon extruded along z).

Matching (:func:`evaluate`): one-to-one, same class only, among pairs with XY IoU > 0 (or above a
reported threshold, 0.25 and 0.5) and centres within ``max_center_distance``; greedy by descending
XY IoU (ties: smaller centre distance, then input order). Greedy is what the paper's evaluation
does in spirit and is stable; an optimal (Hungarian) assignment differs only when one object
overlaps several of the same class, which is rare in a map that is supposed to be one-to-one with
the furniture. Measures over several laps (ghosts of any earlier lap, ids kept, objects deleted
while present) are in :mod:`ltc_cli.tools.lap_history`; definitions in docs/evaluation.md.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ltc_cli.geometry.polygons import pairwise_ious_arrays
from ltc_cli.map.model import SemanticMap
from ltc_cli.tools.eval_objects import (  # noqa: F401  (the IoU helpers and EvalObject: re-exported)
    EvalObject,
    EvaluationError,
    as_eval_object,
    pairwise_ious,
    volume_iou,
    xy_iou,
)
from ltc_cli.tools.lap_history import (  # noqa: F401  (ids_kept: re-exported for callers)
    deleted_while_present,
    former_places,
    ids_kept,
    maintenance_removals,
    object_arrays,
)

# The XY IoU levels reported besides "any overlap" (ScanNet-style 3D benchmarks report 0.25 and 0.5).
IOU_THRESHOLDS = (0.25, 0.5)


# ---------------------------------------------------------------------------------------------
# Matching and metrics


def ratio(num, den):
    """num / den, or None when den is 0: 0/0 is undefined, and 0.0 would flatter nothing and
    mislead (an empty map would read as precision 0)."""
    return num / den if den else None


def _prf(tp: int, fp: int, fn: int):
    """precision, recall and F1 = 2 TP / (2 TP + FP + FN) (the harmonic mean of the two, defined
    even when one of them is not); None where a denominator is 0."""
    return ratio(tp, tp + fp), ratio(tp, tp + fn), ratio(2 * tp, 2 * tp + fp + fn)


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


def _earlier_laps(previous_gt) -> list:
    """The earlier laps' objects, oldest first, from one lap (a ground_truth dict or a list of
    objects) or a sequence of laps (ground_truth dicts or lists of objects)."""
    if previous_gt is None:
        return []
    if isinstance(previous_gt, Mapping):
        return [_objects_and_changes(previous_gt)[0]]
    items = list(previous_gt)
    if not items:  # no earlier lap, or an empty one: no former places either way
        return []
    if all((isinstance(x, Mapping) and "objects" in x) or isinstance(x, (list, tuple)) for x in items):
        return [_objects_and_changes(x)[0] for x in items]
    return [_objects_and_changes(items)[0]]


def _greedy(cand, iou, dist):
    """One-to-one matching of the candidate pairs by descending IoU (ties: nearer centres, then
    input order). Returns (map_match (M,), gt_match (G,)), -1 where unmatched."""
    mi, gi = np.nonzero(cand)
    order = np.lexsort((gi, mi, dist[mi, gi], -iou[mi, gi]))
    map_match = np.full(cand.shape[0], -1)
    gt_match = np.full(cand.shape[1], -1)
    for k in order:
        i, j = mi[k], gi[k]
        if map_match[i] < 0 and gt_match[j] < 0:
            map_match[i], gt_match[j] = j, i
    return map_match, gt_match


def _kinds(map_match, gt_match, cand, iou, same, ghost_iou):
    """Each map object's kind: tp, ghost, duplicate or fp (see :func:`evaluate`)."""
    kind = np.array(["tp"] * len(map_match), dtype=object)
    matched_gt = gt_match >= 0
    for i in np.flatnonzero(map_match < 0):
        row = np.where(cand[i], iou[i], 0.0)
        best_matched = float(np.where(matched_gt & same[i], iou[i], 0.0).max(initial=0))
        if ghost_iou[i] > 0 and ghost_iou[i] >= best_matched:
            kind[i] = "ghost"
        elif row.max(initial=0) > 0 and matched_gt[int(np.argmax(row))]:
            kind[i] = "duplicate"
        else:
            kind[i] = "fp"
    return kind


def evaluate(
    map_objects,
    gt_objects,
    *,
    max_center_distance: float = 3.0,
    seen_only: bool = False,
    min_seen_pixels: int = 1,
    previous_gt=None,
    changes=None,
    iou_thresholds=IOU_THRESHOLDS,
) -> dict:
    """Compare a map with the ground truth (definitions: docs/evaluation.md).

    map_objects: sequence of objects (dicts or objects with id, class, center, yaw, size; see
        :func:`as_eval_object`).
    gt_objects: sequence of ground-truth objects, or a ground_truth.json dict (then its
        ``changes`` are used unless ``changes`` is given).
    max_center_distance: metres; a match also needs the 3D distance between the centres (which is
        also the reported position error) to be at most this.
    seen_only: ground-truth objects with ``seen_pixels < min_seen_pixels`` (the robot never saw
        them) that are not matched are ignored instead of counted as FN. One that *is* matched stays
        a TP (the map object is right), so recall = TP / (TP + FN) stays within [0, 1].
    previous_gt: the earlier laps' ground truth for counting ghosts: one lap (a ground_truth dict or
        a list of objects) or a sequence of laps, oldest first (the last is the previous lap).
    changes: {"moved": [...], "removed": [...]} ids since the previous lap; default: those of
        ``gt_objects`` when it is a dict with changes. Moves are also inferred from the laps.
    iou_thresholds: the XY IoU levels of ``at_iou`` (a TP there needs XY IoU above the level).

    Matching (every level): one-to-one, same class, centres within ``max_center_distance``, XY IoU
    above the level (0 for "any overlap", the top-level figures), greedy by descending XY IoU. As
    the greedy order is by IoU, the matches at level t are exactly the any-overlap matches with IoU
    > t, so TP counts never rise with the level. Thresholds are on the XY IoU the matcher uses (the
    paper's measure); VIoU <= XY IoU always, and is reported as a mean over the TPs.

    Every map object that is not a TP (at any overlap) is an FP, and falls in exactly one of:
      - ``ghost``: same class and XY IoU > 0 with a *former place*, the box of an object in any
        earlier lap that is not in the current lap (removed) or not at that place (moved: centre
        more than 0.1 m away, or listed as moved in ``changes``), at least as much as with any matched
        current ground-truth object of its class (the map still shows an object where it used to be);
      - ``duplicate``: its best same-class ground-truth candidate (XY IoU > 0, centre within
        ``max_center_distance``) was matched by another map object (a second instance of it);
      - otherwise a plain false positive.

    Returns a dict: tp, fp, fn, num_map, num_gt, ignored_gt, precision, recall, f1, recall_seen and
    f1_seen (recall over the ground-truth objects with ``seen_pixels >= min_seen_pixels``; None when
    no ground-truth object says how much of it was seen), mean_xy_iou, mean_viou,
    mean_position_error (over the TPs), duplicates, ghosts, duplicate_ratio, ghost_ratio (over
    num_map), earlier_laps, matches [{map_id, gt_id, class, xy_iou, viou, position_error}], fp_ids,
    fn_ids, duplicate_ids, ghost_ids, ignored_gt_ids, gt_objects [{id, class, center}], per_class
    {class: {num_map, num_gt, tp, fp, fn, precision, recall, f1, mean_xy_iou, mean_viou,
    mean_position_error, duplicates, ghosts}}, iou_measure ("xy_iou") and at_iou {"0.25": {the same
    counts, ratios and means, per_class, fn_ids} ...}. Ratios and means with a zero denominator
    are None.
    """
    if not max_center_distance > 0:
        raise EvaluationError(f"max_center_distance must be > 0, not {max_center_distance}")
    maps = [as_eval_object(o) for o in map_objects]
    gts, gt_changes = _objects_and_changes(gt_objects)
    earlier = _earlier_laps(previous_gt)
    if changes is None:
        changes = gt_changes
    M, G = len(maps), len(gts)

    ca, ya, sa = object_arrays(maps)
    cg, yg, sg = object_arrays(gts)
    iou, viou = pairwise_ious_arrays(ca, ya, sa, cg, yg, sg)
    dist = np.linalg.norm(ca[:, None, :] - cg[None, :, :], axis=2) if M and G else np.zeros((M, G))
    same = np.array([[m.cls == g.cls for g in gts] for m in maps], dtype=bool).reshape(M, G)
    cand = same & (iou > 0) & (dist <= max_center_distance)
    unseen = np.array([g.seen_pixels is not None and g.seen_pixels < min_seen_pixels for g in gts], dtype=bool)
    has_seen = any(g.seen_pixels is not None for g in gts)

    # Former places of objects in any earlier lap, for ghosts.
    former = former_places(gts, earlier, changes) if earlier else []
    ghost_iou = np.zeros(M)
    if former and M:
        iou_former, _ = pairwise_ious_arrays(ca, ya, sa, *object_arrays(former))
        same_former = np.array([[m.cls == f.cls for f in former] for m in maps], dtype=bool)
        ghost_iou = np.where(same_former, iou_former, 0.0).max(axis=1)

    def level(threshold, with_kinds):
        map_match, gt_match = _greedy(cand & (iou > threshold), iou, dist)
        ignored = (gt_match < 0) & unseen if seen_only else np.zeros(G, dtype=bool)
        kind = _kinds(map_match, gt_match, cand, iou, same, ghost_iou) if with_kinds else None

        def summary(map_sel, gt_sel, seen_figures=False):
            tps = [i for i in np.flatnonzero(map_sel) if map_match[i] >= 0]
            tp = len(tps)
            fp = int(map_sel.sum()) - tp
            missed = gt_sel & (gt_match < 0)
            fn = int((missed & ~ignored).sum())
            p, r, f1 = _prf(tp, fp, fn)
            out = {"num_map": int(map_sel.sum()), "num_gt": int(gt_sel.sum()), "tp": tp, "fp": fp,
                   "fn": fn, "precision": p, "recall": r, "f1": f1}
            if seen_figures:
                fn_seen = int((missed & ~unseen).sum())
                out["recall_seen"] = ratio(tp, tp + fn_seen) if has_seen else None
                out["f1_seen"] = ratio(2 * tp, 2 * tp + fp + fn_seen) if has_seen else None
            out["mean_xy_iou"] = _mean([iou[i, map_match[i]] for i in tps])
            out["mean_viou"] = _mean([viou[i, map_match[i]] for i in tps])
            out["mean_position_error"] = _mean([dist[i, map_match[i]] for i in tps])
            if kind is not None:
                out["duplicates"] = int(sum(1 for i in np.flatnonzero(map_sel) if kind[i] == "duplicate"))
                out["ghosts"] = int(sum(1 for i in np.flatnonzero(map_sel) if kind[i] == "ghost"))
            return out

        res = summary(np.ones(M, dtype=bool), np.ones(G, dtype=bool), seen_figures=True)
        res["fn_ids"] = [gts[j].id for j in range(G) if gt_match[j] < 0 and not ignored[j]]
        classes = sorted({m.cls for m in maps} | {g.cls for g in gts})
        map_cls = np.array([m.cls for m in maps], dtype=object)
        gt_cls = np.array([g.cls for g in gts], dtype=object)
        res["per_class"] = {c: summary(map_cls == c, gt_cls == c) for c in classes}
        return res, map_match, ignored, kind

    result, map_match, ignored, kind = level(0.0, True)
    result["ignored_gt"] = int(ignored.sum())
    result["duplicate_ratio"] = ratio(result["duplicates"], M)
    result["ghost_ratio"] = ratio(result["ghosts"], M)
    result["earlier_laps"] = len(earlier)
    result["matches"] = [
        {"map_id": maps[i].id, "gt_id": gts[j].id, "class": maps[i].cls, "xy_iou": float(iou[i, j]),
         "viou": float(viou[i, j]), "position_error": float(dist[i, j])}
        for i, j in enumerate(map_match) if j >= 0
    ]
    result["fp_ids"] = [maps[i].id for i in range(M) if map_match[i] < 0]
    result["duplicate_ids"] = [maps[i].id for i in range(M) if kind[i] == "duplicate"]
    result["ghost_ids"] = [maps[i].id for i in range(M) if kind[i] == "ghost"]
    result["ignored_gt_ids"] = [gts[j].id for j in range(G) if ignored[j]]
    result["gt_objects"] = [{"id": g.id, "class": g.cls, "center": [float(x) for x in g.center]} for g in gts]
    result["iou_measure"] = "xy_iou"
    result["at_iou"] = {f"{t:g}": level(float(t), False)[0] for t in iou_thresholds}
    return result


def map_objects(smap: SemanticMap, rows=None) -> list[dict]:
    """Objects of a map as {id, class, center, yaw, size} (class = top non-other score): the active
    ones, or those of the given table ``rows`` (e.g. removed objects, with the box they had)."""
    t = smap.objects
    rows = smap.active_rows() if rows is None else np.asarray(rows, dtype=np.int64)
    top = t.scores[rows, :-1].argmax(axis=1) if len(rows) else np.zeros(0, int)
    return [
        {"id": int(r + 1), "class": smap.classes[int(c)], "center": t.center[r], "yaw": float(t.yaw[r]),
         "size": t.size[r]}
        for r, c in zip(rows, top)
    ]


def evaluate_map(smap: SemanticMap, gt: dict, previous=None, **kw) -> dict:
    """Metrics of DESIGN.md section 8 for a map (see :func:`evaluate`; ``previous`` is one earlier
    lap's ground truth or a sequence of them, oldest first), plus ``deleted_while_present``: the
    ground-truth objects of this lap that maintenance removed while they were there and the map had
    no other object on them (:func:`ltc_cli.tools.lap_history.deleted_while_present`, from the
    map's event log and the objects' first session and frame), with
    ``lost_gt_ids``: those of them that no map object stands on now (FN). When the laps given
    (earlier ones and this one) are as many as the map's sessions, session k's removals are judged
    against lap k + 1's objects, each removed object being the one it overlapped best in the lap of
    its last detection; otherwise against this lap's."""
    res = evaluate(map_objects(smap), gt, previous_gt=previous, **kw)
    removals = {i: at for i, at in maintenance_removals(smap.events).items() if 1 <= i <= smap.objects.n}
    ids = sorted(removals)
    removed = [as_eval_object(o) for o in map_objects(smap, np.array(ids, dtype=np.int64) - 1)]
    current = _objects_and_changes(gt)[0]
    laps = [*_earlier_laps(previous), current]
    at_removal = at_detection = None
    t = smap.objects
    if len(laps) == len(smap.sessions):
        at_removal = [laps[removals[i][0]] if 0 <= removals[i][0] < len(laps) else None for i in ids]
        at_detection = [laps[s] if 0 <= (s := int(t.last_session[i - 1])) < len(laps) else None for i in ids]
    since = {int(m["gt_id"]): (int(t.first_session[m["map_id"] - 1]), int(t.first_frame[m["map_id"] - 1]))
             for m in res["matches"]}
    d = deleted_while_present(removed, current, gt_at_removal=at_removal, removed_at=[removals[i] for i in ids],
                              mapped_since=since, max_center_distance=kw.get("max_center_distance", 3.0),
                              gt_at_detection=at_detection)
    d["lost_gt_ids"] = sorted(set(d["gt_ids"]) & set(res["fn_ids"]))
    res["deleted_while_present"] = d
    return res

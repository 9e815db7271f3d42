"""Why a map is wrong after a lap: every false positive, missed object and lost id by its cause.

Pure functions over the results of :func:`ltc_cli.tools.evaluate.evaluate_map` (docs/evaluation.md
has the definitions they build on); ``benchmarks/bench_breakdown.py`` runs them on simulated houses.
Objects are anything :func:`ltc_cli.tools.evaluate.as_eval_object` accepts.

Causes, each object counted once, in this order:

- false positive (a map object matched at no overlap): ``phantom`` (its footprint, grown by
  ``phantom_margin`` metres per side, overlaps a recurring false positive of the simulated detector,
  e.g. a poster seen as a tv) and no ground-truth object of its class, ``ghost`` / ``duplicate`` (as the evaluation says), ``mislabel`` (it
  overlaps a ground-truth object of another class: right place, wrong class), ``other``; and at
  XY IoU > 0.25, ``misplaced``: a match at some overlap but not above 0.25.
- missed object (seen, unmatched at any overlap): ``deleted`` (maintenance removed a map object on
  it: ``deleted_eq4`` by eq. 4 non-detections, ``deleted_absent`` by the end-of-session absence
  rule, ``deleted_picture`` as a picture on a wall), ``merged`` (a map object of its class that matches another object covers it), ``mislabel``
  (a map object of another class stands on it, XY IoU > 0.1), ``unconfirmed`` (it was mapped, then pruned as
  unconfirmed), ``never`` (no map object ever stood on it); at XY IoU > 0.25, ``loose``: matched at
  some overlap but not above 0.25.
- loose match (at some overlap, XY IoU <= 0.25), what fails: ``place`` (the box moved onto the
  object's centre would pass), ``shape`` (the object's footprint at the box's centre would pass),
  ``either`` or ``both``.
- lost id (an unchanged object matched after both laps, not to the same map id): ``removed`` (the
  old map object was removed by maintenance and another one built), ``merged`` (the old map object
  was merged into another one), ``rematched`` (the old map object is still active but another one
  matches the object now), ``unmatched`` (the old one is active and nothing matches the object).
"""

from __future__ import annotations

from collections import Counter

import numpy as np

from ltc_cli.geometry.polygons import pairwise_ious_arrays
from ltc_cli.tools.evaluate import as_eval_object, xy_iou
from ltc_cli.tools.lap_history import deleted_while_present, object_arrays

FP_CAUSES = ("phantom", "ghost", "duplicate", "mislabel", "other")
FN_CAUSES = ("deleted_eq4", "deleted_absent", "deleted_picture", "merged", "mislabel", "unconfirmed", "never")
ID_CAUSES = ("removed", "merged", "rematched", "unmatched")
LOOSE_CAUSES = ("place", "shape", "either", "both")


MISLABEL_IOU = 0.1  # a map object of another class on an object is a mislabel from this XY IoU on


def _overlaps(a, b, grow: float = 0.0, min_iou: float = 0.0) -> np.ndarray:
    """(len(a), len(b)) bool: XY footprints overlap (b's grown by ``grow`` metres per side) by more
    than ``min_iou``."""
    if not a or not b:
        return np.zeros((len(a), len(b)), dtype=bool)
    ca, ya, sa = object_arrays(a)
    cb, yb, sb = object_arrays(b)
    iou, _ = pairwise_ious_arrays(ca, ya, sa, cb, yb, sb + np.array([2 * grow, 2 * grow, 0.0]))
    return iou > min_iou


def false_positive_causes(res: dict, map_objs, gt_objs, phantoms=(), phantom_margin: float = 0.15) -> dict:
    """{map id: cause} for the map objects unmatched at any overlap, and "misplaced" for those matched
    at some overlap but not at XY IoU > 0.25 (see the module's doc)."""
    maps = {o.id: o for o in map(as_eval_object, map_objs)}
    gts = [as_eval_object(g) for g in gt_objs]
    phantoms = [as_eval_object(p) for p in phantoms]
    ghosts, dups = set(res["ghost_ids"]), set(res["duplicate_ids"])
    out = {}
    for mid in res["fp_ids"]:
        m = maps[mid]
        own = [g for g in gts if g.cls == m.cls]
        if _overlaps([m], phantoms, phantom_margin).any() and not _overlaps([m], own).any():
            out[mid] = "phantom"
        elif mid in ghosts:
            out[mid] = "ghost"
        elif mid in dups:
            out[mid] = "duplicate"
        elif _overlaps([m], [g for g in gts if g.cls != m.cls], min_iou=MISLABEL_IOU).any():
            out[mid] = "mislabel"
        else:
            out[mid] = "other"
    return _below_quarter(res, "map_id", "misplaced", out)


def missed_causes(res: dict, map_objs, gt_objs, seen_ids, removed_eq4=(), removed_absent=(),
                  removed_unconfirmed=(), removed_picture=()) -> dict:
    """{ground-truth id: cause} for the seen objects unmatched at any overlap, and "loose" for those
    matched at some overlap but not at XY IoU > 0.25. ``removed_*``: the removed map objects (with the
    box they had) by the reason of their removal."""
    maps = [as_eval_object(o) for o in map_objs]
    gts = {g.id: g for g in map(as_eval_object, gt_objs)}
    matched_map = {m["map_id"] for m in res["matches"]}
    lap_gts = list(gts.values())
    by_eq4 = set(deleted_while_present([as_eval_object(o) for o in removed_eq4], lap_gts)["gt_ids"])
    by_absent = set(deleted_while_present([as_eval_object(o) for o in removed_absent], lap_gts)["gt_ids"])
    by_picture = set(deleted_while_present([as_eval_object(o) for o in removed_picture], lap_gts)["gt_ids"])
    if "deleted_while_present" in res:
        # Only what the evaluator judged deleted while present (by the lap of each removed object's
        # last detection): a box removed after its object left is no cause of another's miss.
        judged = set(res["deleted_while_present"]["gt_ids"])
        by_eq4, by_absent, by_picture = by_eq4 & judged, by_absent & judged, by_picture & judged
    out = {}
    for gid in res["fn_ids"]:
        if gid not in seen_ids:
            continue
        g = gts[gid]
        on = [m for m in maps if _overlaps([m], [g]).any()]
        if gid in by_eq4:
            out[gid] = "deleted_eq4"
        elif gid in by_absent:
            out[gid] = "deleted_absent"
        elif gid in by_picture:
            out[gid] = "deleted_picture"
        elif any(m.cls == g.cls and m.id in matched_map for m in on):
            out[gid] = "merged"
        elif _overlaps([m for m in on if m.cls != g.cls], [g], min_iou=MISLABEL_IOU).any():
            out[gid] = "mislabel"
        elif _overlaps([as_eval_object(o) for o in removed_unconfirmed if _cls(o) == g.cls], [g]).any():
            out[gid] = "unconfirmed"
        else:
            out[gid] = "never"
    return _below_quarter(res, "gt_id", "loose", out)


def loose_causes(res: dict, map_objs, gt_objs, threshold: float = 0.25) -> dict:
    """{ground-truth id: what fails} for the matches at some overlap but XY IoU <= ``threshold``:
    ``place`` when the map box moved onto the object's centre (its own size and yaw kept) would
    pass and the object's footprint at the box's centre would not, ``shape`` the other way round,
    ``either`` when both would, ``both`` when neither would (the box is off and of the wrong shape).

    Which of the two a map needs, a better localiser (place) or better box fitting (shape), is the
    question: the realistic simulated houses' loose matches are mostly ``place``."""
    maps = {o.id: o for o in map(as_eval_object, map_objs)}
    gts = {g.id: g for g in map(as_eval_object, gt_objs)}
    out = {}
    for m in res["matches"]:
        if m["xy_iou"] > threshold:
            continue
        box, g = maps[m["map_id"]], gts[m["gt_id"]]
        moved = xy_iou((g.center, box.yaw, box.size), g) > threshold
        reshaped = xy_iou((box.center, g.yaw, g.size), g) > threshold
        out[g.id] = "either" if moved and reshaped else "place" if moved else "shape" if reshaped else "both"
    return out


def _below_quarter(res: dict, key: str, cause: str, out: dict) -> dict:
    """``out`` with ``cause`` for the ``key`` ids of the matches at XY IoU <= 0.25."""
    out.update({m[key]: cause for m in res["matches"] if m["xy_iou"] <= 0.25})
    return out


def _cls(obj) -> str:
    return as_eval_object(obj).cls


def id_change_causes(before: dict, after: dict, status_of, lost_gt_ids) -> dict:
    """{ground-truth id: cause} for the objects whose id the map did not keep.

    before, after: evaluation results after laps k-1 and k; lost_gt_ids: from
    :func:`~ltc_cli.tools.lap_history.ids_kept`; status_of(map id) -> "active", "removed" or "merged"
    (the old map object's status after lap k)."""
    old = {int(m["gt_id"]): int(m["map_id"]) for m in before["matches"]}
    new = {int(m["gt_id"]): int(m["map_id"]) for m in after["matches"]}
    out = {}
    for gid in lost_gt_ids:
        status = status_of(old[gid])
        if status in ("removed", "merged"):
            out[gid] = status
        else:
            out[gid] = "rematched" if gid in new else "unmatched"
    return out


def tally(causes: dict, names) -> Counter:
    """Counts of each cause (every name present, 0 when absent)."""
    c = Counter(causes.values())
    return Counter({n: c.get(n, 0) for n in (*names, *sorted(set(c) - set(names)))})

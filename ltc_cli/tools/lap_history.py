"""Measures over several laps of one house (docs/evaluation.md): where objects used to stand, which
objects stayed put, whether the map kept their ids, and whether maintenance deleted objects that
were still there.

Pure functions, no I/O. Ground-truth and map objects are anything with ``id``, ``cls``,
``center (3,)``, ``yaw`` and ``size (3,)`` (e.g. :class:`ltc_cli.tools.eval_objects.EvalObject`);
evaluation results are the dicts :func:`ltc_cli.tools.evaluate.evaluate` returns.

Identity across laps is the ground truth's object id: the ground-truth format's ``changes`` lists
(moved / removed / added ids since the previous lap) already rely on ids that persist from lap to
lap, and ``ltc simulate`` writes them so.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ltc_cli.geometry.polygons import pairwise_ious_arrays

# An object is "unchanged" between two laps when its centre moved at most this far (metres). Large
# enough for annotation noise, small next to any real move (ltc simulate moves objects by
# decimetres to metres).
UNCHANGED_DISTANCE = 0.1
END_OF_SESSION = 2**62  # the frame of an end-of-session event: after every frame of its session


def unchanged(a, b, tol: float = UNCHANGED_DISTANCE) -> bool:
    """True when ground-truth objects ``a`` and ``b`` (of two laps) are the same object at the same
    place: same id, same class, centres within ``tol`` metres."""
    return (
        a.id == b.id
        and a.cls == b.cls
        and float(np.linalg.norm(np.asarray(a.center) - np.asarray(b.center))) <= tol
    )


def former_places(current, earlier_laps, changes=None, tol: float = UNCHANGED_DISTANCE) -> list:
    """The boxes where an object stood in some earlier lap and no longer stands now.

    current: the current lap's ground-truth objects.
    earlier_laps: sequence of earlier laps' ground-truth objects, oldest first (the last one is the
        previous lap).
    changes: the current lap's ``changes`` ({"moved": ids, "removed": ids}), relative to the previous
        lap; those ids' previous-lap boxes are former places even if they moved less than ``tol``.

    An earlier-lap object is at a former place when the current lap holds no object :func:`unchanged`
    from it (removed, or moved more than ``tol``). Returns those earlier-lap objects (one per lap in
    which the object stood there; duplicates are harmless because only the best overlap is used).
    """
    now = {o.id: o for o in current}
    listed = set()
    if changes:
        listed = {int(i) for i in changes.get("moved", [])} | {int(i) for i in changes.get("removed", [])}
    places = []
    for k, lap in enumerate(earlier_laps):
        is_previous = k == len(earlier_laps) - 1
        for o in lap:
            c = now.get(o.id)
            if c is None or not unchanged(o, c, tol) or (is_previous and o.id in listed):
                places.append(o)
    return places


def ids_kept(before: Mapping, after: Mapping, tol: float = UNCHANGED_DISTANCE) -> dict:
    """Whether the map kept the ids of the objects that did not change between two laps.

    before, after: :func:`~ltc_cli.tools.evaluate.evaluate` results of the map after lap k-1 and
    after lap k against those laps' ground truth (they carry ``gt_objects`` and ``matches``).

    An unchanged ground-truth object (same id and class in both laps, centre within ``tol``) that
    was matched after lap k-1 is *kept* when it is matched after lap k to the same map object id.
    One that is unmatched after lap k (deleted, or replaced by an object that no longer overlaps) is
    not kept. Unchanged objects unmatched after lap k-1 had no id to keep and are left out.

    Returns {"unchanged": unchanged objects, "tracked": of those, matched after lap k-1, "kept",
    "share": kept / tracked (None when nothing was tracked), "lost_gt_ids": tracked but not kept}.
    """

    def gt_by_id(res):
        return {int(g["id"]): g for g in res["gt_objects"]}

    def map_id_of(res):
        return {int(m["gt_id"]): int(m["map_id"]) for m in res["matches"]}

    gb, ga = gt_by_id(before), gt_by_id(after)
    mb, ma = map_id_of(before), map_id_of(after)
    same = [
        i for i, g in gb.items()
        if i in ga and g["class"] == ga[i]["class"]
        and float(np.linalg.norm(np.subtract(g["center"], ga[i]["center"]))) <= tol
    ]
    tracked = [i for i in same if i in mb]
    kept = [i for i in tracked if ma.get(i) == mb[i]]
    return {
        "unchanged": len(same),
        "tracked": len(tracked),
        "kept": len(kept),
        "share": len(kept) / len(tracked) if tracked else None,
        "lost_gt_ids": sorted(set(tracked) - set(kept)),
    }


def _event_field(event, key):
    return event.get(key) if isinstance(event, Mapping) else getattr(event, key, None)


def maintenance_removals(events) -> dict[int, tuple[int, int]]:
    """{map object id: (session, frame) it was removed at} for the removals by non-detections (map
    maintenance, eq. 4 and the absence rule): events of kind ``removed`` whose detail starts with
    "other" (the `other` score overtook the object's class). Other removals (e.g. "unconfirmed": a
    one-off detection never seen again) are not counted. An end-of-session removal (frame -1) is
    at frame ``END_OF_SESSION``, after every frame; a missing session or frame is -1. A removal
    that a later "returned:" event undid (``maintenance.return_after_misses``: the object came back
    with its id) is no removal: the map holds the object."""
    out = {}
    for e in events:
        detail = str(_event_field(e, "detail") or "")
        if _event_field(e, "kind") == "updated" and detail.startswith("returned:"):
            out.pop(int(_event_field(e, "object_id")), None)
        if _event_field(e, "kind") == "removed" and detail.startswith("other"):
            session, frame = (_event_field(e, k) for k in ("session", "frame"))
            session = -1 if session is None else int(session)
            frame = -1 if frame is None else int(frame)
            if frame < 0 and session >= 0:
                frame = END_OF_SESSION
            out[int(_event_field(e, "object_id"))] = (session, frame)
    return out


def maintenance_removed_ids(events) -> list[int]:
    """Ids of the map objects removed by non-detections (see :func:`maintenance_removals`)."""
    return sorted(maintenance_removals(events))


def object_arrays(objs):
    """center (N, 3), yaw (N,), size (N, 3) of a sequence of objects with those attributes."""
    if not objs:
        return np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3))
    return (np.array([o.center for o in objs], dtype=np.float64),
            np.array([o.yaw for o in objs], dtype=np.float64),
            np.array([o.size for o in objs], dtype=np.float64))


def deleted_while_present(removed_objects, gt_objects, *, gt_at_removal=None, removed_at=None,
                          mapped_since=None, max_center_distance: float = 3.0, gt_at_detection=None) -> dict:
    """Ground-truth objects present in the current lap that maintenance removed (at any time) while
    they stood where their removed map object was, and the map had no other object on them.

    removed_objects: the map objects removed by non-detections (see :func:`maintenance_removals`),
        with the box and class they had when removed.
    gt_objects: the current lap's ground-truth objects.
    gt_at_removal: per removed object, the ground-truth objects of the lap it was removed in (None,
        or a None entry: the current lap's). A chair rightly removed after it was carried away is
        not "deleted while present" because another chair stands at that place laps later.
    removed_at, mapped_since: per removed object, when it was removed, and {ground-truth id: when
        the map object that stands on it now was created}, as comparable (session, frame) pairs.
        A removal after the object's present map object was made removed a duplicate: the map
        still had the object, under the id it has now (listed as ``duplicates_removed``).
    gt_at_detection: per removed object, the ground-truth objects of the lap of its last detection
        (None, or a None entry: judged by the lap it was removed in alone). The object it overlaps
        best among those of its class is the one it was a view of; it counts only when that very
        object (same id) still stood on its box in the lap it was removed in. A plant's box removed
        after the plant was taken away is right, even where another plant brought in lap 2 touches
        its box by a few centimetres.

    Each removed object is a view of the ground-truth object it overlaps best among those of its
    class in the lap it was removed in (XY IoU > 0, centres within ``max_center_distance``; ties:
    nearer centre); one with no such object was rightly removed (or was never right). It counts when
    that object is present in the current lap. Not one-to-one: an object deleted and rebuilt twice
    has two removed map objects on it and counts once.

    Returns {"count": ground-truth objects with a removed map object on them, "present": ground-truth
    objects, "share": count / present (None when there are none), "gt_ids", "map_ids",
    "duplicates_removed": map ids}.
    """
    G = len(gt_objects)
    present = {int(g.id) for g in gt_objects}
    n = len(removed_objects)
    gt_at_removal = [None] * n if gt_at_removal is None else gt_at_removal
    removed_at = [None] * n if removed_at is None else removed_at
    gt_at_detection = [None] * n if gt_at_detection is None else gt_at_detection
    mapped_since = mapped_since or {}
    gt_ids, map_ids, duplicates = set(), [], []
    for r, lap_gt, det_gt, when in zip(removed_objects, gt_at_removal, gt_at_detection, removed_at):
        lap_gt = gt_objects if lap_gt is None else lap_gt
        if det_gt is None:
            j = _best_same_class(r, lap_gt, max_center_distance)
        else:
            k = _best_same_class(r, det_gt, max_center_distance)
            if k is None:  # never a view of an object of its class
                continue
            # That object, if it still stood on the box when the box was removed.
            same = [i for i, g in enumerate(lap_gt) if int(g.id) == int(det_gt[k].id)]
            j = same[0] if same and _best_same_class(r, [lap_gt[same[0]]], max_center_distance) == 0 else None
        if j is None or int(lap_gt[j].id) not in present:
            continue
        gid = int(lap_gt[j].id)
        if when is not None and gid in mapped_since and tuple(mapped_since[gid]) < tuple(when):
            duplicates.append(int(r.id))
            continue
        gt_ids.add(gid)
        map_ids.append(int(r.id))
    return {
        "count": len(gt_ids),
        "present": G,
        "share": len(gt_ids) / G if G else None,
        "gt_ids": sorted(gt_ids),
        "map_ids": sorted(map_ids),
        "duplicates_removed": sorted(duplicates),
    }


def _best_same_class(obj, gt_objects, max_center_distance: float):
    """Index of the ground-truth object of ``obj``'s class it overlaps best (XY IoU > 0, centres
    within ``max_center_distance``; ties: nearer centre), or None."""
    if not gt_objects:
        return None
    ca, ya, sa = object_arrays([obj])
    cg, yg, sg = object_arrays(gt_objects)
    iou = pairwise_ious_arrays(ca, ya, sa, cg, yg, sg)[0][0]
    dist = np.linalg.norm(cg - ca[0], axis=1)
    same = np.array([obj.cls == g.cls for g in gt_objects], dtype=bool)
    cand = np.flatnonzero(same & (iou > 0) & (dist <= max_center_distance))
    if not cand.size:
        return None
    # Best IoU, then the nearer centre: lexsort's last key is the primary one.
    return int(cand[np.lexsort((dist[cand], -iou[cand]))[0]])

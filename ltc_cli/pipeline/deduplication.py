"""Instance de-duplication (DESIGN.md 1.2, the end of stage 2): which in-view map objects are one
object and merge after a frame, and which of two keeps its id. Pure numpy over boxes; the mapper's
merge step (merging.py) applies these decisions.

Eq. 2 and containment find duplicates of one class (the paper); the other rules here find one object
under two labels and a later partial view of a Defined object (a part standing under its object:
stands.py).
"""

from __future__ import annotations

import numpy as np

from ltc_cli.geometry.boxes import Boxes
from ltc_cli.geometry.polygons import footprint_circles_meet, paired_ious
from ltc_cli.pipeline.association import (
    apart_grounds, footprint_gaps, half_diagonals, pairwise_containment, similar_volume, thresholds_for, too_wide,
    too_long_together, unlike_heights,
)
from ltc_cli.pipeline.integration import PART_INSIDE_SHARE, shares_inside


def duplicate_pairs(boxes: Boxes, top: np.ndarray, distance, same: float, other: float,
                    need_same: float | None, need_other: float | None,
                    other_volume_ratio: float | None = None, reach: float | None = None,
                    other_scale: float | None = None, min_overlap: float | None = None,
                    defined: np.ndarray | None = None, established: np.ndarray | None = None,
                    labels_apart: bool = False, max_width: np.ndarray | None = None,
                    scores: np.ndarray | None = None,
                    min_evidence: float | None = None,
                    well_seen: np.ndarray | None = None,
                    same_scale: float | None = None, paired: bool = False) -> list[tuple[float, int, int]]:
    """Pairs of map objects (M boxes in view) that match each other: [(distance, a, b)], a < b,
    sorted by distance (the closest pairs merge first).

    ``distance(one, many)`` is the association metric (``paired``: it also takes K boxes paired
    with K, :class:`~ltc_cli.protocols.Metric`). Two objects match when their distance is
    under the threshold of their classes, or, with containment on, when one lies mostly inside the
    other (one object seen in parts); objects of different classes only when of similar volume
    (``other_volume_ratio``, :func:`similar_volume`).

    ``reach``: the metric's distance is never less than the boxes' centre distance less their half
    diagonals (:func:`within_reach`); then only pairs within ``reach`` metres beyond that are
    compared (the same pairs result). None: every pair.

    ``min_overlap`` (a share of the smaller footprint) holds for pairs with a partial box; two
    Defined boxes (``defined`` (M,) bool) are compared on all 8 vertices and are exempt, unless both
    are ``established`` ((M,) bool: made in an earlier session). Two objects the map kept apart
    through a whole session are two things; on a revisit a box that shrank to one monitor's
    visible part put eq. 2 under the threshold of its neighbour's (tum-fr1-rpy, 0.45 m apart).
    With ``labels_apart`` two Defined boxes of different top classes are not exempt either: one
    object under two labels shares its ground, and a whole cup and a whole mouse 26 cm apart on a
    desk came under eq. 2's other-class threshold over the six vertices both showed.
    ``well_seen`` ((M,) bool: detected at least ``defined_apart_detections`` times) counts as
    ``established`` for that test, within a session too: two Defined screens side by side, each
    detected a dozen times and more, sharing no ground, are two screens (tum-fr1-rpy: eq. 2 over
    their 8 vertices 0.34 m, under the 0.4 of one class, and the averaged box stood between the
    two monitors, on neither).

    ``other_scale``, ``same_scale``: the thresholds of two classes and of one are at most this many
    times the larger half diagonal of the pair (:func:`~ltc_cli.pipeline.association.size_caps`;
    None: the fixed thresholds).

    ``max_width`` (C+1,): per class, the widest footprint that joins a partial object of another
    class by containment, inside or around it (:func:`~ltc_cli.pipeline.association.too_wide`;
    None: any).

    ``min_evidence`` with ``scores`` (M, C+1): two objects of different top classes join by
    containment only when one's class vector gives the other's top class at least this score
    (:func:`shared_evidence`; None: by containment alone), and, when both are ``established``,
    by the metric only when each gives the other's.
    """
    m = len(boxes)
    if m < 2:
        return []
    near = None
    evidence = mutual = None
    if min_evidence is not None and scores is not None:
        evidence, mutual = (shared_evidence(scores, top, min_evidence, both) for both in (False, True))
    halves = half_diagonals(boxes.size)
    if reach is not None:
        near = np.linalg.norm(boxes.center[:, None] - boxes.center[None], axis=-1) <= \
            halves[:, None] + halves[None] + max(same, other, reach) + 1e-6  # within_reach, all pairs at once
    if need_same:
        inside = pairwise_containment(boxes, near)
        inside = np.maximum(inside, inside.T)  # either one inside the other
        vol = np.prod(boxes.size, axis=1)
        other_ok = np.where(similar_volume(vol[:, None], vol[None, :], other_volume_ratio), need_other or np.inf, np.inf)
        need = np.where(top[:, None] == top[None, :], need_same, other_ok)
        contained = inside >= need
        if evidence is not None:
            contained &= (top[:, None] == top[None, :]) | evidence
        if max_width is not None:
            # A too wide box joins a box of another class by containment only when that one is
            # Defined (which then replaces its box), whichever of the two contains the other.
            wide = too_wide(top, boxes.size, max_width)
            part = np.ones(m, dtype=bool) if defined is None else ~np.asarray(defined, dtype=bool)
            blocked = (wide[:, None] & part[None, :]) | (wide[None, :] & part[:, None])
            contained &= ~(blocked & (top[:, None] != top[None, :]))
    boxes.corners  # noqa: B018  computed once, and shared by the pairs' takes
    i, j = np.triu_indices(m, k=1)  # every pair once, a < b
    if near is not None:
        i, j = i[near[i, j]], j[near[i, j]]
    if i.size == 0:
        return []
    larger = np.maximum(halves[i], halves[j])  # as size_caps
    caps = [None if scale is None else scale * larger for scale in (other_scale, same_scale)]
    thr = thresholds_for(top[i], top[j], same, other, *caps)
    measure = np.ones(len(i), dtype=bool)
    if reach is not None:
        # The metric's distance is at least the centres' distance less both half diagonals
        # (within_reach): a pair farther by that bound than its own threshold joins by containment
        # alone, and its distance is measured only then (it orders the merges).
        bound = np.linalg.norm(boxes.center[i] - boxes.center[j], axis=1) - halves[i] - halves[j]
        measure = (bound <= thr + 1e-6) | (contained[i, j] if need_same else False)
    dist = np.full(len(i), np.inf)
    dist[measure] = pair_distances(boxes, i[measure], j[measure], distance, paired)
    close = dist <= thr
    if min_overlap is not None and close.any():
        # eq. 2 over the vertices visible in both: a partial box's visible corners can sit on
        # its neighbour's (two monitors edge to edge); one object's pieces share their ground.
        apart = apart_grounds(boxes.take(i), boxes.take(j), close, min_overlap)
        if defined is not None:  # all 8 vertices of two Defined boxes are compared
            defined = np.asarray(defined, bool)
            exempt = defined[i] & defined[j]
            if established is not None or well_seen is not None:
                held = np.zeros(m, bool) if established is None else np.asarray(established, bool)
                if well_seen is not None:
                    held = held | np.asarray(well_seen, bool)
                exempt &= ~(held[i] & held[j])
            if labels_apart:
                exempt &= top[i] == top[j]
            apart &= ~exempt
        close &= ~apart
    if mutual is not None and established is not None:
        # Two objects of different classes that the map kept apart through a whole session:
        # one object under two labels carries both by now, each of them; a monitor and the foot
        # the detector calls "mouse" do not (tum-fr1-rpy's second half revisiting the first
        # half's map: by eq. 2 the monitor's 23 detections went into the foot's box, and it was
        # "mouse"), nor a keyboard and the mouse beside it whose masks took a strip of the keys
        # (its vector gave keyboard 0.19, the keyboard's mouse nothing; with the int8 model the
        # mouse went into the keyboard on a revisit).
        established = np.asarray(established, bool)
        close &= (top[j] == top[i]) | ~(established[i] & established[j]) | mutual[i, j]
    if need_same:
        close |= contained[i, j]
    k = np.flatnonzero(close)
    return sorted(zip(dist[k].tolist(), i[k].tolist(), j[k].tolist()))


def pair_distances(boxes: Boxes, i: np.ndarray, j: np.ndarray, distance, paired: bool = False) -> np.ndarray:
    """(K,) the metric's distance of each pair of boxes (boxes[i[k]] as the detection, boxes[j[k]]
    as the candidate), ``i`` sorted. ``paired``: ``distance`` takes K boxes paired with K (one call);
    otherwise one call per box of ``i`` against its candidates, as a metric is called in stage 2."""
    if len(i) == 0:
        return np.zeros(0)
    if paired:
        return np.asarray(distance(boxes.take(i), boxes.take(j)), dtype=float)
    out = np.empty(len(i))
    starts = np.flatnonzero(np.r_[True, i[1:] != i[:-1]])
    for s, e in zip(starts, np.r_[starts[1:], len(i)]):
        out[s:e] = distance(boxes.take(slice(i[s], i[s] + 1)), boxes.take(j[s:e]))
    return out


def greedy_merges(pairs: list[tuple[float, int, int]], ids: np.ndarray, survivor=None,
                  disjoint: bool = False) -> list[tuple[int, int]]:
    """(keep, drop) index pairs from :func:`duplicate_pairs`, closest first, each object at most
    once dropped. The older object (smaller id) keeps its id, unless ``survivor(older, newer)``
    (indices) names the newer one (see :func:`label_survivor`).

    ``disjoint``: each object in at most one of the merges, kept or dropped. A merge changes the
    kept box, and the pairs were found on the boxes before it: a later pair of the kept object may
    no longer hold. The caller finds the pairs again on the merged boxes."""
    gone: set = set()
    out = []
    for _, a, b in pairs:
        if a in gone or b in gone:
            continue
        older, newer = (a, b) if ids[a] < ids[b] else (b, a)
        keep = survivor(older, newer) if survivor is not None else older
        drop = newer if keep == older else older
        out.append((keep, drop))
        gone.add(drop)
        if disjoint:
            gone.add(keep)
    return out


def label_survivor(top_older: int, top_newer: int, top_merged: int, by_label: bool,
                   newer_only_now: bool = False) -> bool:
    """True when, of two map objects that merge, the newer one keeps its id: the two had different
    top classes and the merged class vector names the newer one's. The user knows the map by
    "tv 2"; when a monitor's foot, mapped first as "mouse 1", joins it, "tv 2" is the object that is
    still there. by_label False: the older id always stays (the paper's de-duplication keeps one).

    ``newer_only_now``: the newer object was made in this session and the older one in an earlier
    session. Then the older id stays whatever the label: it is an id the map already gave the
    user, the newer one is minutes old and nobody knows it yet."""
    return bool(by_label and not newer_only_now and top_older != top_newer and top_merged == top_newer)


def relabel_pairs(boxes: Boxes, top: np.ndarray, min_iou: float | None, other_volume_ratio: float | None
                  ) -> list[tuple[float, int, int]]:
    """Pairs of map objects (M boxes in view) of different top classes that are one object under two
    labels: footprints overlapping by XY IoU at least ``min_iou`` and volumes similar
    (:func:`similar_volume`). [(1 - IoU, a, b)], a < b, the most overlapping first; none when
    ``min_iou`` is None.

    A detector that calls a chair "couch" in runs of nearby views makes a couch object beside the
    chair object: the other-class threshold of eq. 2 is tighter and the two boxes, each from a few
    views, rarely share vertices closely enough. Sitting on the same footprint with a similar volume,
    they are one thing; which label it gets is for the class evidence to say (eq. 3).
    """
    m = len(boxes)
    if min_iou is None or m < 2:
        return []
    # Footprints are clipped only for the pairs the other tests leave, and whose bounding circles meet.
    i, j = np.triu_indices(m, k=1)
    vol = np.prod(boxes.size, axis=1)
    keep = (top[i] != top[j]) & similar_volume(vol[i], vol[j], other_volume_ratio) \
        & footprint_circles_meet(boxes.center[i], boxes.size[i], boxes.center[j], boxes.size[j])
    i, j = i[keep], j[keep]
    iou = paired_ious(boxes.center[i], boxes.yaw[i], boxes.size[i], boxes.center[j], boxes.yaw[j], boxes.size[j])[0]
    ok = iou >= min_iou
    return sorted(zip((1.0 - iou[ok]).tolist(), i[ok].tolist(), j[ok].tolist()))


def labelled_part_pairs(boxes: Boxes, top: np.ndarray, scores: np.ndarray | None, min_label: float | None,
                        volume_share: float, inside: float = PART_INSIDE_SHARE) -> list[tuple[float, int, int]]:
    """Pairs of map objects (M boxes in view, top classes (M,), class vectors (M, C+1)) in which a
    small object is a part of a larger one of another top class by both place and evidence: under
    ``volume_share`` of its volume, ``inside`` of it within the larger box, and its own class
    vector giving the larger one's class at least ``min_label``. [(1 - that score, a, b)], a < b,
    the surest first; none when ``min_label`` is None.

    A cup on a table is inside the table's box too, but nothing in its evidence says table; the
    back of a chair that the detector calls "tv" in some views and "chair" in others (tum-fr1-rpy
    read backwards: tv 0.52, chair 0.38, inside the chair's box) is the chair under two labels,
    which the issue asks to fuse by evidence, not by size."""
    m = len(boxes)
    if min_label is None or scores is None or m < 2:
        return []
    vol = np.prod(boxes.size, axis=1)
    # [a, b]: a small enough, of another class, and saying b's class enough; then the boxes, by b.
    said = np.asarray(scores)[:, np.asarray(top)] >= min_label
    cand = (vol[:, None] < volume_share * vol[None, :]) & (top[:, None] != top[None, :]) & said
    out = []
    for b in np.flatnonzero(cand.any(axis=0)):  # b the larger one
        small = np.flatnonzero(cand[:, b])
        within = shares_inside(boxes.row(int(b), False), boxes.center[small], boxes.yaw[small], boxes.size[small])
        out.extend((1.0 - float(scores[a, top[b]]), min(int(a), int(b)), max(int(a), int(b)))
                   for a, w in zip(small, within) if w >= inside)
    return sorted(out)


def partial_defined_pairs(boxes: Boxes, top: np.ndarray, defined: np.ndarray, first_session: np.ndarray,
                          max_gap: float | None, min_volume: float = 1.0) -> list[tuple[float, int, int]]:
    """Pairs of map objects (M boxes in view, top classes (M,), Defined flags (M,) bool, sessions of
    their first detection (M,)) in which a partial object is the later view of a Defined object of
    its class: first detected in a later session, at least ``min_volume`` times its volume, and with
    a footprint within ``max_gap`` metres of it (:func:`footprint_gaps`, z ranges overlapping).
    [(gap, a, b)], a < b, nearest first; none when ``max_gap`` is None.

    On a revisit, a view of a complete object cut by the image border makes a partial box grown
    along the axis it did not see (a 0.5 m chair became a 1.4 m box beside it on tum-fr1-rpy): too
    far by eq. 2, not enough inside to merge by containment, but touching it. A partial box never
    reshapes a Defined one (DESIGN.md 1.3), so the merge costs the complete box nothing. Within one
    session the same picture is as often a second object not yet seen whole (chairs side by side
    at a table: the simulator lost a chair so), hence the later session; a smaller partial box is
    for containment to judge, hence the volume.
    """
    m = len(boxes)
    if max_gap is None or m < 2:
        return []
    vol = np.prod(boxes.size, axis=1)
    out = []
    for a in np.flatnonzero(~defined):
        rest = np.flatnonzero(defined & (top == top[a]) & (first_session < first_session[a])
                              & (vol[a] >= min_volume * vol))
        if rest.size == 0:
            continue
        gaps = footprint_gaps(boxes.take(slice(int(a), int(a) + 1)), boxes.take(rest))
        out.extend((float(g), min(int(a), int(b)), max(int(a), int(b))) for g, b in zip(gaps, rest) if g <= max_gap)
    return sorted(out)


def adjoining_part_pairs(boxes: Boxes, top: np.ndarray, defined: np.ndarray, share_by_class: np.ndarray | None,
                         max_gap: float | None) -> list[tuple[float, int, int]]:
    """Pairs of map objects (M boxes in view, top classes (M,), Defined flags (M,)) that are pieces
    of one long object: the same top class, one with a ``share_by_class`` (C+1,) over 0, not both
    Defined (two whole things), and footprints apart by at most ``max_gap`` metres or that share of
    the longer side of the two (z ranges overlapping). [(gap, a, b)], a < b, nearest first; none
    when either is None. See :func:`enclosed_part` for the merged box.

    The detection-side rule (:func:`~ltc_cli.pipeline.association.adjoining_partial`) joins a view
    of a table's end to the box of its other end; two pieces made before the view that joins them
    stay apart, three boxes for one dining table with chairs all round (held-out house 201)."""
    m = len(boxes)
    if share_by_class is None or max_gap is None or m < 2:
        return []
    long_side = boxes.size[:, :2].max(axis=1)
    out = []
    for a in np.flatnonzero(np.asarray(share_by_class)[top] > 0):
        rest = np.flatnonzero((top == top[a]) & (np.arange(m) > a) & ~(defined[a] & defined))
        if rest.size == 0:
            continue
        gaps = footprint_gaps(boxes.take(slice(int(a), int(a) + 1)), boxes.take(rest))
        allowed = np.maximum(float(max_gap), share_by_class[top[a]] * np.maximum(long_side[a], long_side[rest]))
        out.extend((float(g), int(a), int(b)) for g, b, ok in zip(gaps, rest, gaps <= allowed) if ok)
    return sorted(out)


def enclosed_part(a, b) -> bool:
    """Of two pieces of one object (:func:`adjoining_part_pairs`), one Defined and one partial:
    True when the Defined one's footprint is the smaller, so that it is a part, not the whole,
    and the merged box encloses both (otherwise the Defined box stands, as in every merge)."""
    whole, part = (a, b) if a.defined else (b, a)
    return float(whole.size[0] * whole.size[1]) < float(part.size[0] * part.size[1])


def beyond_class_length(merged_top: int, merged_long: float, tops, longs, limit: np.ndarray) -> bool:
    """Whether a merge of objects of classes ``tops`` (footprints' longer sides ``longs``) into one
    of class ``merged_top`` whose footprint's longer side is ``merged_long`` leaves a thing of a
    class never that long (``limit`` (C+1,): ``association.max_union_length``, inf: any). As in
    :func:`~ltc_cli.pipeline.association.too_long_together`, a side of that class already longer
    alone (a monitor's foot called "mouse") is no such thing, and the rule says nothing of it.
    Under a noisy depth (tum-fr1-rpy, a stereo-like error 0.01 Z^2) a 2-detection "mouse" merged
    with a 0.47 m "book" in the frame that made it, and became a 0.47 m mouse: the mouse's label,
    the book's Defined box."""
    lim = float(limit[merged_top])
    if not np.isfinite(lim) or merged_long <= lim:
        return False
    return all(long <= lim for top, long in zip(tops, longs) if top == merged_top)


#: Keys of :func:`merge_pairs` from this on are pieces of one object (:func:`adjoining_part_pairs`).
PIECES_KEY = 4e6


def shared_evidence(scores: np.ndarray, top: np.ndarray, min_score: float, both: bool = False) -> np.ndarray:
    """(M, M) bool: pairs of objects (class vectors scores (M, C+1), top classes (M,)) of which one
    gives the other's top class at least ``min_score`` (``both``: each gives the other's). A chair
    the detector calls couch in some views carries couch in its vector, and its couch-labelled
    pieces chair; a chair standing in a table's partial box carries no table, nor the table chair."""
    scores = np.asarray(scores)
    given = scores[:, top] >= min_score  # [a, b]: a's vector gives b's top class
    return (given & given.T) if both else (given | given.T)


def merge_pairs(boxes: Boxes, top: np.ndarray, distance, a_cfg: dict, reach: float | None = None,
                defined: np.ndarray | None = None, first_session: np.ndarray | None = None,
                session: int | None = None, scores: np.ndarray | None = None,
                part_volume: float | None = None,
                adjoin_share: np.ndarray | None = None,
                max_width: np.ndarray | None = None,
                n_det: np.ndarray | None = None,
                max_union: np.ndarray | None = None, paired: bool = False) -> list[tuple[float, int, int]]:
    """The pairs of in-view map objects (M boxes, top classes (M,)) to merge after a frame, by the
    association settings ``a_cfg``: true duplicates first (:func:`duplicate_pairs`: eq. 2, or one
    inside the other by ``merge_containment``, default ``containment``), then one object under two
    labels (:func:`relabel_pairs`, keys past any distance), then the later partial view of a Defined
    object (:func:`partial_defined_pairs`, when ``defined`` and ``first_session`` (M,) are given).
    The overlap rules all stand down with ``containment`` off (the paper: vertex distance only).
    ``reach``: as for duplicate_pairs. ``session``: the current one; with ``established_apart`` and
    ``first_session``, objects made before it are ``established`` for duplicate_pairs.
    ``adjoin_share`` (C+1,): pieces of one long object last (:func:`adjoining_part_pairs`; None: none).
    ``max_width`` (C+1,): as for duplicate_pairs (``container_max_width``); ``scores`` (M, C+1):
    the class vectors, for the labelled parts and for duplicate_pairs' ``merge_other_class_evidence``.
    ``n_det`` (M,): detections so far, for ``defined_apart_detections`` (None: that rule stands down).
    ``max_union`` (C+1,): no two objects of one class merge into a footprint longer than this
    (:func:`~ltc_cli.pipeline.association.union_diameters`; None: any). ``paired``: as for
    duplicate_pairs."""
    overlap = a_cfg["containment"] is not None
    established = first_session < session if a_cfg["established_apart"] and first_session is not None \
        and session is not None else None
    well_seen = None if n_det is None or a_cfg["defined_apart_detections"] is None \
        else np.asarray(n_det) >= a_cfg["defined_apart_detections"]
    pairs = duplicate_pairs(boxes, top, distance, a_cfg["threshold_same_class"], a_cfg["threshold_other_class"],
                            overlap and (a_cfg["merge_containment"] or a_cfg["containment"]),
                            a_cfg["containment_other_class"], a_cfg["other_class_volume_ratio"], reach,
                            a_cfg["other_class_scale"], a_cfg["merge_min_overlap"], defined, established,
                            a_cfg["labels_apart"], max_width, scores, a_cfg["merge_other_class_evidence"],
                            well_seen, a_cfg["same_class_scale"], paired)
    two_labels = relabel_pairs(boxes, top, a_cfg["merge_other_class_iou"] if overlap else None,
                               a_cfg["other_class_volume_ratio"])
    later = partial_defined_pairs(boxes, top, defined, first_session, a_cfg["merge_partial_defined_gap"],
                                  a_cfg["merge_partial_defined_volume"]) \
        if overlap and defined is not None and first_session is not None else []
    parts = labelled_part_pairs(boxes, top, scores, a_cfg["part_label_share"], part_volume) \
        if overlap and part_volume is not None else []
    pieces = adjoining_part_pairs(boxes, top, defined, adjoin_share, a_cfg["partial_adjoin_gap"]) \
        if overlap and defined is not None else []
    out = pairs + [(1e6 + k, a, b) for k, a, b in two_labels] + [(2e6 + g, a, b) for g, a, b in later] \
        + [(3e6 + k, a, b) for k, a, b in parts] + [(PIECES_KEY + g, a, b) for g, a, b in pieces]
    if max_union is not None and out and np.isfinite(max_union[top]).any():
        a, b = np.array([p[1] for p in out]), np.array([p[2] for p in out])
        foot = boxes.corners[:, :4, :2]
        long = (top[a] == top[b]) & too_long_together(foot[a], foot[b], max_union[top[a]])
        out = [p for p, drop in zip(out, long) if not drop]
    if defined is None or a_cfg["other_class_height_ratio"] is None:
        return out
    return [(d, a, b) for d, a, b in out if top[a] == top[b] or not unlike_heights(
        boxes.center[a, 2], boxes.size[a, 2], defined[a], boxes.center[b, 2], boxes.size[b, 2], defined[b],
        a_cfg["other_class_height_ratio"])]

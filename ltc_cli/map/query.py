"""Queries over a map's objects: vectorised filters returning row indices, then plain records.

Pure functions over a :class:`~ltc_cli.mapping.SemanticMap` (no I/O, no click). Every filter is a
numpy boolean mask over the whole object table, so a query on 100,000 objects costs a few
milliseconds; only the rows that pass are turned into Python records.

An object's *class* is the argmax of its class vector over the map's classes, ``other`` excluded
(``other`` leading means the object was removed, so it is never a class to report); its
*confidence* is that class's score.
"""

from __future__ import annotations

import gc
import math
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ltc_cli.errors import LtcError
from ltc_cli.map.model import ACTIVE, REMOVED, SemanticMap


@contextmanager
def paused_gc():
    """Pause the cyclic garbage collector while building many small dicts and lists.

    Records hold no reference cycles, so reference counting frees them anyway; but every few
    hundred new containers the collector would scan the growing heap again, which makes building
    100,000 records 3-6 times slower.
    """
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()


class QueryError(LtcError):
    """A query that cannot be answered (unknown class name, bad point or radius)."""


@dataclass
class Query:
    """What to select. Empty / None fields do not filter.

    classes: class names; an object passes when its class is any of them.
    near: a point (2,) or (3,) in the map frame, metres. With 2 values the distance between centres
        is measured in the XY plane; with 3 it is the 3-D distance. Needs ``radius``.
    radius: metres; objects whose centre is within ``radius`` of ``near`` (inclusive) pass.
    min_confidence: objects whose confidence is >= this pass.
    ids: object ids (row + 1).
    removed: select the objects that maintenance removed (status 1) instead of the active ones.
    """

    classes: Sequence[str] = ()
    near: Sequence[float] | None = None
    radius: float | None = None
    min_confidence: float | None = None
    ids: Sequence[int] = ()
    removed: bool = False


@dataclass
class QueryResult:
    """rows: (K,) selected row indices into the object table, in id order; total: how many
    objects the query chose from (active ones, or removed ones with ``removed``);
    distance: (K,) metres from ``near`` when the query had a point, else None."""

    rows: np.ndarray
    total: int
    distance: np.ndarray | None = None
    query: Query = field(default_factory=Query)


def classify(smap: SemanticMap) -> tuple[np.ndarray, np.ndarray]:
    """(class index (N,) int, confidence (N,) float) of every object in the table."""
    scores = smap.objects.scores[:, :-1]
    if scores.shape[0] == 0 or scores.shape[1] == 0:
        return np.zeros(scores.shape[0], dtype=np.int64), np.zeros(scores.shape[0])
    idx = scores.argmax(axis=1)
    return idx, np.take_along_axis(scores, idx[:, None], axis=1)[:, 0]


def _check(query: Query, smap: SemanticMap, map_path) -> None:
    unknown = [c for c in query.classes if c not in smap.classes]
    if unknown:
        raise QueryError(f"unknown class {', '.join(map(repr, unknown))}; this map's classes are: "
                         f"{', '.join(smap.classes)}", map_path)
    if (query.near is None) != (query.radius is None):
        raise QueryError("a point (near) and a radius go together")
    if query.near is not None:
        if len(query.near) not in (2, 3) or not all(math.isfinite(float(v)) for v in query.near):
            raise QueryError(f"near must be 2 or 3 finite numbers, not {list(query.near)}")
        if not (math.isfinite(float(query.radius)) and float(query.radius) >= 0):
            raise QueryError(f"radius must be a finite number >= 0, not {query.radius}")


def select(smap: SemanticMap, query: Query, map_path=None) -> QueryResult:
    """Rows of the objects that pass every filter of ``query`` (vectorised; see :class:`Query`).

    Raises QueryError (naming ``map_path``) for a class name the map does not have.
    """
    _check(query, smap, map_path)
    t = smap.objects
    keep = t.status == (REMOVED if query.removed else ACTIVE)
    total = int(keep.sum())
    if query.classes or query.min_confidence is not None:
        cls_idx, conf = classify(smap)
    if query.classes:
        wanted = np.array([smap.classes.index(c) for c in query.classes], dtype=np.int64)
        keep &= np.isin(cls_idx, wanted)
    if query.min_confidence is not None:
        keep &= conf >= float(query.min_confidence)
    if query.ids:
        keep &= np.isin(t.ids, np.asarray(list(query.ids), dtype=np.int64))
    dist = None
    if query.near is not None:
        p = np.asarray(query.near, dtype=np.float64)
        d = np.linalg.norm(t.center[:, : len(p)] - p, axis=1)
        keep &= d <= float(query.radius)
    rows = np.flatnonzero(keep)
    if query.near is not None:
        dist = d[rows]
    return QueryResult(rows=rows, total=total, distance=dist, query=query)


def removal_events(smap: SemanticMap) -> dict[int, object]:
    """object id -> its last ``removed`` Event (session, frame, frame_key, detail)."""
    smap.require_events("removed")
    out = {}
    for ev in smap.events:
        if ev.kind == "removed":
            out[int(ev.object_id)] = ev
    return out


def records(smap: SemanticMap, result: QueryResult) -> list[dict]:
    """One plain dict per selected row (JSON-ready; metres and radians in the map frame).

    Keys: id, class, confidence, center [x, y, z], yaw, size [sx, sy, sz], defined, n_det, n_nondet,
    first_seen / last_seen {session, frame}; ``distance`` (metres) when the query had a point;
    ``removed`` {session, frame, frame_key, detail} when the query selected removed objects.
    """
    rows = result.rows
    t = smap.objects
    cls_idx, conf = classify(smap)
    # Column-wise tolist() then zip: one pass of C conversions instead of numpy scalars per field.
    cols = zip(
        t.ids[rows].tolist(), cls_idx[rows].tolist(), conf[rows].round(6).tolist(),
        t.center[rows].round(6).tolist(), t.yaw[rows].round(6).tolist(), t.size[rows].round(6).tolist(),
        t.defined[rows].tolist(), t.n_det[rows].tolist(), t.n_nondet[rows].tolist(),
        t.first_session[rows].tolist(), t.first_frame[rows].tolist(),
        t.last_session[rows].tolist(), t.last_frame[rows].tolist(),
    )
    names = smap.classes
    with paused_gc():
        out = [{
            "id": oid, "class": names[ci], "confidence": cf, "center": c, "yaw": yaw, "size": s,
            "defined": dfd, "n_det": nd, "n_nondet": nn,
            "first_seen": {"session": fs, "frame": ff}, "last_seen": {"session": ls, "frame": lf},
        } for oid, ci, cf, c, yaw, s, dfd, nd, nn, fs, ff, ls, lf in cols]
    if result.distance is not None:
        for rec, d in zip(out, result.distance.round(6).tolist()):
            rec["distance"] = d
    if result.query.removed:
        evs = removal_events(smap)
        for rec in out:
            ev = evs.get(rec["id"])
            rec["removed"] = (
                {"session": int(ev.session), "frame": int(ev.frame), "frame_key": ev.frame_key, "detail": ev.detail}
                if ev is not None else {"session": None, "frame": None, "frame_key": None, "detail": ""}
            )
    return out


# -- flat rows for the table and CSV forms ---------------------------------------------------------

def flat_columns(result: QueryResult) -> list[str]:
    """Column names of :func:`flat_rows` for this result (CSV header)."""
    cols = ["id", "class", "confidence", "x", "y", "z", "yaw", "sx", "sy", "sz", "defined", "n_det",
            "n_nondet", "first_session", "first_frame", "last_session", "last_frame"]
    if result.distance is not None:
        cols.append("distance")
    if result.query.removed:
        cols += ["removed_session", "removed_frame", "removed_frame_key", "removed_detail"]
    return cols


def flat_rows(recs: list[dict]) -> list[list]:
    """Each record as a flat list matching :func:`flat_columns`."""
    out = []
    for r in recs:
        row = [r["id"], r["class"], r["confidence"], *r["center"], r["yaw"], *r["size"], r["defined"],
               r["n_det"], r["n_nondet"], r["first_seen"]["session"], r["first_seen"]["frame"],
               r["last_seen"]["session"], r["last_seen"]["frame"]]
        if "distance" in r:
            row.append(r["distance"])
        if "removed" in r:
            rm = r["removed"]
            row += [rm["session"], rm["frame"], rm["frame_key"], rm["detail"]]
        out.append(row)
    return out


def table_lines(recs: list[dict], result: QueryResult) -> list[str]:
    """An aligned text table: one header line, then one line per record.

    Numbers are right-aligned with fixed decimals (centimetres for positions, 0.001 rad for yaw),
    text left-aligned; "conf" is the class's score, "detections" / "missed" count the frames that
    detected the object / should have and did not; ``why`` (the removal detail) is last so that long texts do not break alignment.
    """
    # Words, not abbreviations: "detections" the frames that detected it, "missed" the frames that
    # should have and did not (non-detections); last seen in which session, at which of its frames.
    header = ["id", "class", "conf", "x", "y", "z", "yaw", "sx", "sy", "sz", "defined", "detections", "missed",
              "last session", "last frame"]
    right = [True, False, True, True, True, True, True, True, True, True, False, True, True, True, True]
    if result.distance is not None:
        header.append("dist")
        right.append(True)
    if result.query.removed:
        header += ["removed (session frame)", "why"]
        right += [False, False]
    body = []
    for r in recs:
        c, s = r["center"], r["size"]
        cells = [str(r["id"]), r["class"], f"{r['confidence']:.3f}", f"{c[0]:.2f}", f"{c[1]:.2f}",
                 f"{c[2]:.2f}", f"{r['yaw']:.3f}", f"{s[0]:.2f}", f"{s[1]:.2f}", f"{s[2]:.2f}",
                 "yes" if r["defined"] else "no", str(r["n_det"]), str(r["n_nondet"]),
                 str(r["last_seen"]["session"]), str(r["last_seen"]["frame"])]
        if "distance" in r:
            cells.append(f"{r['distance']:.2f}")
        if "removed" in r:
            rm = r["removed"]
            cells += [f"{rm['session']} {rm['frame_key']}" if rm["session"] is not None else "?", rm["detail"]]
        body.append(cells)
    widths = [max([len(h)] + [len(b[i]) for b in body]) for i, h in enumerate(header)]

    def fmt(cells):
        parts = [(v.rjust(w) if r else v.ljust(w)) for v, w, r in zip(cells, widths, right)]
        return "  ".join(parts).rstrip()

    return [fmt(header)] + [fmt(b) for b in body]

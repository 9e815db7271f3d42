"""What changed between visits: objects added, removed and moved after a session, from the map's
object table and its event log. Pure functions over a loaded map (no I/O, no printing).

Against the map as it stood at the end of session ``since`` (0-based, as ``ltc info`` numbers them):

- **removed**: an object that was in the map then and that maintenance removed in a later session
  (its ``removed`` event names the session, frame and why); it is reported where it last stood.
- **added**: an active object that did not exist then: neither it nor any object merged into it was
  created by session ``since`` (the table's ``first_session`` is the earliest of its merge lineage).
- **moved**: a removal and an addition of the same class in the same session, at most
  ``move_radius`` apart in XY: the robot saw the old place empty and the object at a new place.
  Pairs are taken nearest first, so each removal and each addition is in at most one move. A pair
  less than ``min_move`` apart whose footprints overlap, or less than ``MIN_SMALL_MOVE`` apart, is
  no change at all: the object is still in its place and the map replaced its box by a new one (a
  removal after a few bad views, then a fresh detection). A small thing whose new box shares no
  ground with its old one has moved, however little (a mug 0.3 m along the desk).

Objects merged into another (duplicates found and fused) are neither removed nor added, and an
addition where a session up to ``since`` named a thing of its class once (an object it removed as
unconfirmed, at the same place by :func:`in_place`) is no change either: the thing was there, and
a later visit's detector confirmed what the earlier one glimpsed (``ChangeReport.confirmed``).
Nor is an addition at a place no session up to ``since`` looked at (less than ``FIRST_SEEN_SHARE``
of its footprint's cells in their ``coverage``, map/coverage.py): a room the robot had not entered
yet (``ChangeReport.first_seen``). Maps whose sessions kept no coverage report every addition.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ltc_cli.errors import LtcError
from ltc_cli.geometry.polygons import paired_ious
from ltc_cli.map.coverage import footprint_cells, sessions_seen
from ltc_cli.map.model import ACTIVE, REMOVED, SemanticMap
from ltc_cli.map.query import classify, removal_events

#: Default largest XY distance (m) of a removal and an addition that count as one move: furniture
#: goes to another wall, small things to another room's table (measured in docs/decisions.md).
MOVE_RADIUS = 6.0
#: Nearer than this (m), a removal and an addition of one class whose footprints overlap are the
#: same object in its place.
MIN_MOVE = 0.5
#: Nearer than this (m), they are the same object in its place whatever their footprints: two
#: visits' localisers disagree by a few centimetres, and a bottle's box is about as wide.
MIN_SMALL_MOVE = 0.15
#: The word the event log's reason for a removal as unconfirmed starts with
#: (ltc_cli/pipeline/reasons.py ``unconfirmed_detail``).
UNCONFIRMED = "unconfirmed:"
#: An addition is a change only where the earlier sessions saw at least this share of its footprint's
#: cells: a thing there then would have been in their depth.
FIRST_SEEN_SHARE = 0.5
KINDS = ("added", "removed", "moved")


class ChangesError(LtcError):
    """A change report that cannot be made (a session the map does not have)."""


@dataclass
class Change:
    """One change. ``object_id`` / ``center`` / ``yaw`` / ``size``: the object as it is now (added,
    moved) or where it last stood (removed); ``from_id`` / ``from_center``: a moved object's old
    object and place; ``session``: the session the change happened in; ``detail``: why it was removed."""

    kind: str
    object_id: int
    cls: str
    session: int
    center: list
    yaw: float
    size: list
    from_id: int | None = None
    from_center: list | None = None
    detail: str = ""

    @property
    def distance(self) -> float | None:
        if self.from_center is None:
            return None
        return float(np.hypot(self.center[0] - self.from_center[0], self.center[1] - self.from_center[1]))

    def as_dict(self) -> dict:
        d = {"change": self.kind, "id": self.object_id, "class": self.cls, "session": self.session,
             "center": [round(v, 6) for v in self.center], "yaw": round(self.yaw, 6),
             "size": [round(v, 6) for v in self.size]}
        if self.kind == "moved":
            d.update({"from_id": self.from_id, "from_center": [round(v, 6) for v in self.from_center],
                      "distance": round(self.distance, 6)})
        if self.kind == "removed":
            d["why"] = self.detail
        return d


@dataclass
class ChangeReport:
    since: int
    sessions: int  # sessions in the map
    changes: list[Change]
    replaced: int = 0  # objects still in place whose box the map replaced (not changes)
    confirmed: int = 0  # objects an earlier session named once at their place (not changes)
    first_seen: int = 0  # objects at places no earlier session looked at (not changes)

    def count(self, kind: str) -> int:
        return sum(c.kind == kind for c in self.changes)


def default_since(smap: SemanticMap) -> int:
    """The session before the last one: what the latest visit changed."""
    return max(len(smap.sessions) - 2, 0)


def _change(smap: SemanticMap, kind: str, row: int, cls_idx, session: int, detail: str = "") -> Change:
    t = smap.objects
    return Change(kind, int(row + 1), smap.classes[int(cls_idx[row])], int(session), t.center[row].tolist(),
                  float(t.yaw[row]), t.size[row].tolist(), detail=detail)


def map_changes(smap: SemanticMap, since: int | None = None, move_radius: float = MOVE_RADIUS,
                min_move: float = MIN_MOVE, map_path=None) -> ChangeReport:
    """The objects added, removed and moved after session ``since`` (default: :func:`default_since`);
    ChangesError naming ``map_path`` for a session the map does not have."""
    n_sessions = len(smap.sessions)
    since = default_since(smap) if since is None else int(since)
    if not -1 <= since < max(n_sessions, 1):
        raise ChangesError(f"session {since} is not in this map (sessions 0..{n_sessions - 1}; "
                           "-1 compares with an empty map)", map_path)
    for name, v in (("move radius", move_radius), ("minimum move", min_move)):
        if not (np.isfinite(v) and v >= 0):
            raise ChangesError(f"{name} must be a finite number >= 0, not {v}", map_path)
    t = smap.objects
    cls_idx, _ = classify(smap)
    removals = removal_events(smap)
    removed = [
        _change(smap, "removed", r, cls_idx, removals[r + 1].session, removals[r + 1].detail)
        for r in np.flatnonzero((t.status == REMOVED) & (t.first_session <= since))
        if r + 1 in removals and removals[r + 1].session > since
    ]
    added = [_change(smap, "added", r, cls_idx, t.first_session[r])
             for r in np.flatnonzero((t.status == ACTIVE) & (t.first_session > since))]
    # Named once by a session the report compares with (at or before ``since``): it was there.
    glimpsed = [_change(smap, "removed", r, cls_idx, ev.session) for r in np.flatnonzero(t.status == REMOVED)
                if (ev := removals.get(r + 1)) is not None and ev.session <= since
                and str(ev.detail).startswith(UNCONFIRMED)]
    seen_once = glimpsed_at(added, glimpsed, min_move)
    confirmed = int(seen_once.sum())
    added = [a for a, once in zip(added, seen_once) if not once]
    moves = _pair_moves(removed, added, move_radius)
    used_r = {id(m[0]) for m in moves}
    used_a = {id(m[1]) for m in moves}
    added = [c for c in added if id(c) not in used_a]
    unseen = first_seen(added, seen_before(smap, since))
    changes = [c for c, new in zip(added, unseen) if not new] + [c for c in removed if id(c) not in used_r]
    replaced = 0
    for old, new in moves:
        new.kind, new.from_id, new.from_center = "moved", old.object_id, old.center
        if in_place(old, new, min_move):
            replaced += 1
        else:
            changes.append(new)
    changes.sort(key=lambda c: (c.session, KINDS.index(c.kind), c.object_id))
    return ChangeReport(since, n_sessions, changes, replaced, confirmed, int(unseen.sum()))


def seen_before(smap: SemanticMap, since: int) -> tuple[set, float] | None:
    """(cell keys, cell size) that sessions 0..``since`` saw (their rows' ``coverage``); None when
    one of them kept none (written before ltc kept it, or unreadable) or they used other cell sizes."""
    seen = sessions_seen(smap.sessions[: since + 1])
    return None if seen is None else (set(seen[0].tolist()), seen[1])


def first_seen(added: list[Change], seen: tuple[set, float] | None, share: float = FIRST_SEEN_SHARE) -> np.ndarray:
    """(A,) bool: the additions less than ``share`` of whose footprint's cells are in ``seen``
    (:func:`seen_before`); none when ``seen`` is None."""
    out = np.zeros(len(added), dtype=bool)
    if seen is None:
        return out
    keys, cell = seen
    for k, c in enumerate(added):
        under = footprint_cells(np.asarray(c.center), c.yaw, np.asarray(c.size), cell)
        out[k] = sum(int(u) in keys for u in under.tolist()) < share * len(under)
    return out


def glimpsed_at(added: list[Change], glimpsed: list[Change], min_move: float = MIN_MOVE,
                min_small_move: float = MIN_SMALL_MOVE) -> np.ndarray:
    """(A,) bool: the additions at whose place (:func:`in_place`) one of ``glimpsed`` (objects
    removed as unconfirmed) of their class stood. Candidate pairs come from a grid of
    ``min_move`` cells (a glimpse within ``min_move`` lies in the 3 x 3 cells around an addition),
    so that a map of many sessions' glimpses costs a fraction of a second."""
    out = np.zeros(len(added), dtype=bool)
    if not added or not glimpsed or min_move <= 0:
        return out
    boxes = {}
    for name, group in (("a", added), ("g", glimpsed)):
        boxes[name] = (np.array([c.cls for c in group]), np.array([c.center for c in group], dtype=np.float64),
                       np.array([c.yaw for c in group], dtype=np.float64),
                       np.array([c.size for c in group], dtype=np.float64))
    (a_cls, a_c, a_yaw, a_size), (g_cls, g_c, g_yaw, g_size) = boxes["a"], boxes["g"]
    cells: dict = {}
    for k, key in enumerate(zip(g_cls.tolist(), *np.floor(g_c[:, :2] / min_move).astype(np.int64).T.tolist())):
        cells.setdefault(key, []).append(k)
    pa, pg = [], []
    for k, (cls, i, j) in enumerate(zip(a_cls.tolist(), *np.floor(a_c[:, :2] / min_move).astype(np.int64).T.tolist())):
        for di in (-1, 0, 1):
            for dj in (-1, 0, 1):
                near = cells.get((cls, i + di, j + dj), ())
                pa += [k] * len(near)
                pg += near
    if not pa:
        return out
    pa, pg = np.array(pa), np.array(pg)
    d = np.hypot(a_c[pa, 0] - g_c[pg, 0], a_c[pa, 1] - g_c[pg, 1])
    keep = d < min_move
    pa, pg, d = pa[keep], pg[keep], d[keep]
    same = d < min_small_move
    iou, _ = paired_ious(g_c[pg], g_yaw[pg], g_size[pg], a_c[pa], a_yaw[pa], a_size[pa])
    out[pa[same | (iou > 0.0)]] = True
    return out


def in_place(old: Change, new: Change, min_move: float = MIN_MOVE, min_small_move: float = MIN_SMALL_MOVE) -> bool:
    """Whether a removal ``old`` and an addition ``new`` of one class are the object in its place:
    less than ``min_move`` apart with footprints that overlap, or less than ``min_small_move`` apart."""
    d = float(np.hypot(new.center[0] - old.center[0], new.center[1] - old.center[1]))
    if d >= min_move:
        return False
    if d < min_small_move:
        return True
    iou, _ = paired_ious(*(np.array([v], dtype=np.float64) for v in (old.center, old.yaw, old.size, new.center,
                                                                      new.yaw, new.size)))
    return bool(iou[0] > 0.0)


def _pair_moves(removed: list[Change], added: list[Change], radius: float) -> list[tuple[Change, Change]]:
    """(removal, addition) pairs of one class and one session within ``radius``, nearest first."""
    cands = []
    for i, old in enumerate(removed):
        for j, new in enumerate(added):
            if old.cls == new.cls and old.session == new.session:
                d = float(np.hypot(new.center[0] - old.center[0], new.center[1] - old.center[1]))
                if d <= radius:
                    cands.append((d, i, j))
    pairs, took_i, took_j = [], set(), set()
    for _, i, j in sorted(cands):
        if i not in took_i and j not in took_j:
            took_i.add(i)
            took_j.add(j)
            pairs.append((removed[i], added[j]))
    return pairs


# -- flat forms for the table and CSV --------------------------------------------------------------

COLUMNS = ["change", "class", "id", "session", "x", "y", "z", "from_id", "from_x", "from_y", "distance", "why"]


def flat_rows(report: ChangeReport) -> list[list]:
    rows = []
    for c in report.changes:
        fx, fy = (c.from_center[0], c.from_center[1]) if c.from_center is not None else (None, None)
        rows.append([c.kind, c.cls, c.object_id, c.session, *(round(v, 6) for v in c.center), c.from_id,
                     None if fx is None else round(fx, 6), None if fy is None else round(fy, 6),
                     None if c.distance is None else round(c.distance, 6), c.detail])
    return rows


def table_lines(report: ChangeReport) -> list[str]:
    """An aligned text table (positions in metres, to the centimetre)."""
    header = ["change", "class", "id", "session", "x", "y", "z", "from", "moved by", "why"]
    body = []
    for c in report.changes:
        frm = "" if c.from_id is None else f"#{c.from_id} at {c.from_center[0]:.2f},{c.from_center[1]:.2f}"
        body.append([c.kind, c.cls, str(c.object_id), str(c.session), f"{c.center[0]:.2f}", f"{c.center[1]:.2f}",
                     f"{c.center[2]:.2f}", frm, "" if c.distance is None else f"{c.distance:.2f} m", c.detail])
    widths = [max([len(h)] + [len(b[i]) for b in body]) for i, h in enumerate(header)]
    right = {2, 3, 4, 5, 6, 8}
    return ["  ".join(v.rjust(w) if i in right else v.ljust(w) for i, (v, w) in enumerate(zip(r, widths))).rstrip()
            for r in [header] + body]

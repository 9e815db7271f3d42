"""The semantic map in memory: the object table (struct of arrays), its XY grid index, the event
log, and everything else a map file holds. No I/O (the store saves and loads it) and no stage logic.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, field

import numpy as np

from ltc_cli.geometry.boxes import Box, Boxes


def top_class(scores: np.ndarray) -> np.ndarray:
    """The class index (...,) of class vectors (..., C+1): the argmax over the map's classes, with
    `other` (last) left out, so an object about to be removed still says what it was."""
    return np.asarray(scores)[..., :-1].argmax(axis=-1)


ACTIVE, REMOVED, MERGED = 0, 1, 2

# Columns added after format 1: a map written before them reads them as zeros.
ADDED_COLUMNS = frozenset({"n_clear", "nondet_view", "clear_session", "clear_in_session", "clear_since_det",
                           "det_view", "det_views", "through_since_det", "n_clear_det", "det_span", "n_flat",
                           "det_holes"})


STATUS_NAMES = {ACTIVE: "active", REMOVED: "removed", MERGED: "merged"}


# Columns of the object table: name -> (per-object shape suffix, dtype). "scores" is (C+1,).
COLUMNS = {
    "center": ((3,), np.float64),
    "yaw": ((), np.float64),
    "size": ((3,), np.float64),
    "visible": ((8,), bool),
    "defined": ((), bool),
    "n_det": ((), np.int64),
    "n_nondet": ((), np.int64),
    # Frames in which the object was clearly visible (enough pixels for a non-detection), detected
    # or not: with n_nondet, the detector's hit rate on it (the learnt per-class detection rate).
    "n_clear": ((), np.int64),
    # Of those, the frames in which it was detected: the hit rate is n_clear_det / n_clear. Misses
    # count as non-detections only from a new view, so n_clear - n_nondet overstates the hits.
    "n_clear_det": ((), np.int64),
    # Over those frames, the sum of the share of its box's pixels without a depth reading: a dark
    # screen or a shiny basin gives none, and its holes are then its own (maintenance.absent_holes_share).
    "det_holes": ((), np.float64),
    # Camera position (3) and forward axis (3) at the object's last counted non-detection (zeros:
    # none yet): misses from nearly the same view are one piece of evidence, not several.
    "nondet_view": ((6,), np.float64),
    # The session of the object's latest clear view, and how many clear views it had in it: an
    # object of an earlier session seen clearly again and again in a session that never detects it
    # is gone (maintenance.absent_after_views).
    "clear_session": ((), np.int64),
    "clear_in_session": ((), np.int64),
    # Clear views without a detection since the object's last detection, over sessions
    # (maintenance.absent_quiet_sessions).
    "clear_since_det": ((), np.int64),
    # Of those, the views that saw through the object's box (depth past its middle): the absence
    # rule's evidence that its place is empty (maintenance.absent_through_views).
    "through_since_det": ((), np.int64),
    # Detections dropped as pictures flat on a wall that fell in its box (pipeline/pictures.py).
    "n_flat": ((), np.int64),
    # Camera position and forward axis (6) at the object's last detection from a new view, and how
    # many such distinct views detected it (maintenance.min_detection_views).
    "det_view": ((6,), np.float64),
    "det_views": ((), np.int64),
    # The least and greatest camera position, then forward axis, along x, y, z and the horizontal
    # diagonals (5 + 5 + 5 + 5), over the views that detected it: whether two of them lie apart,
    # whatever their order (views.span_views).
    "det_span": ((20,), np.float64),
    "status": ((), np.int8),
    "first_session": ((), np.int64),
    "first_frame": ((), np.int64),
    "last_session": ((), np.int64),
    "last_frame": ((), np.int64),
}


class ObjectTable:
    """Every object the map ever held, as columns (structure of arrays); row r has id r + 1.

    Removed and merged objects stay in the table with their status, so nothing is ever lost.
    """

    def __init__(self, n_classes: int, capacity: int = 64):
        self.n_classes = n_classes
        self.n = 0
        self.cols: dict[str, np.ndarray] = {}
        for name, (shape, dtype) in COLUMNS.items():
            self.cols[name] = np.zeros((capacity,) + shape, dtype=dtype)
        self.cols["scores"] = np.zeros((capacity, n_classes + 1))

    def __getattr__(self, name):
        cols = self.__dict__.get("cols")
        if cols is not None and name in cols:
            return cols[name][: self.n]
        raise AttributeError(name)

    @property
    def ids(self) -> np.ndarray:
        return np.arange(1, self.n + 1, dtype=np.int64)

    def append(self, **values) -> int:
        if self.n == len(self.cols["yaw"]):
            for name, arr in self.cols.items():
                grown = np.zeros((max(2 * len(arr), 64),) + arr.shape[1:], dtype=arr.dtype)
                grown[: self.n] = arr[: self.n]
                self.cols[name] = grown
        row = self.n
        self.n += 1
        for name, value in values.items():
            self.cols[name][row] = value
        return row

    def boxes(self, rows) -> Boxes:
        c = self.cols
        return Boxes(c["center"][rows], c["yaw"][rows], c["size"][rows], c["visible"][rows])

    def box(self, row) -> Box:
        c = self.cols
        return Box(c["center"][row].copy(), float(c["yaw"][row]), c["size"][row].copy(),
                   c["visible"][row].copy(), bool(c["defined"][row]))

    def set_box(self, row, box: Box) -> None:
        c = self.cols
        c["center"][row], c["yaw"][row], c["size"][row] = box.center, box.yaw, box.size
        c["visible"][row], c["defined"][row] = box.visible, box.defined

    @classmethod
    def from_columns(cls, columns: dict) -> "ObjectTable":
        scores = np.asarray(columns["scores"], dtype=np.float64)
        t = cls(scores.shape[1] - 1, capacity=max(len(scores), 64))
        t.n = len(scores)
        t.cols["scores"][: t.n] = scores
        for name in COLUMNS:
            if name in columns:  # maps written before a column existed read it as zeros
                t.cols[name][: t.n] = columns[name]
        if "n_clear_det" not in columns and "n_clear" in columns:
            # The best a map written before the column can say: its clear views less its misses.
            t.cols["n_clear_det"][: t.n] = np.maximum(t.n_clear - t.n_nondet, 0)
        return t

    def columns(self) -> dict:
        return {name: arr[: self.n] for name, arr in self.cols.items()}


class GridIndex:
    """Active objects by the XY grid cells their footprint touches.

    Per-frame queries touch only the cells around the camera, so the cost of a frame does not grow
    with the number of objects elsewhere in the map.

    Two parts answer a query together: the objects a session starts with, indexed at once by
    :meth:`build` into sorted numpy arrays (cell code -> rows, a 100k-object map in tens of ms where
    a Python loop took 1.6 s), and the objects inserted since, in a dict of sets. Inserting or
    removing a row takes it out of the arrays' part (a mask), so each row is in one part only.
    """

    # Cells are coded i * 2**32 + (j + 2**31) in int64: grid coordinates beyond +-2**31 cells (the
    # 2 m cells put that at 4 million km) go to the dict part instead.
    _SPAN = 1 << 31

    def __init__(self, cell: float):
        self.cell = float(cell)
        self.cells: dict[tuple, set] = defaultdict(set)
        self.where: dict[int, list] = {}
        self.base_codes = np.zeros(0, np.int64)  # sorted cell codes, one per (cell, row) pair
        self.base_rows = np.zeros(0, np.int64)
        self.base_live = np.zeros(0, bool)  # by row: still indexed in the arrays' part

    def _cells_of(self, center, size):
        r = 0.5 * float(np.hypot(size[0], size[1]))
        i0, i1 = int(np.floor((center[0] - r) / self.cell)), int(np.floor((center[0] + r) / self.cell))
        j0, j1 = int(np.floor((center[1] - r) / self.cell)), int(np.floor((center[1] + r) / self.cell))
        return [(i, j) for i in range(i0, i1 + 1) for j in range(j0, j1 + 1)]

    def build(self, rows, centers_xyz, sizes_xyz) -> None:
        """Index ``rows`` (K,) with their centres and sizes (K, 3) at once, as if each were
        :meth:`insert`-ed (same cells, same query answers). For an empty index only."""
        rows = np.asarray(rows, dtype=np.int64)
        centers_xyz, sizes_xyz = np.asarray(centers_xyz, np.float64), np.asarray(sizes_xyz, np.float64)
        # The same float operations as _cells_of, element by element, so the same cells.
        r = 0.5 * np.hypot(sizes_xyz[:, 0], sizes_xyz[:, 1])
        ij0 = np.floor((centers_xyz[:, :2] - r[:, None]) / self.cell)
        ij1 = np.floor((centers_xyz[:, :2] + r[:, None]) / self.cell)
        fits = (np.isfinite(ij0).all(1) & np.isfinite(ij1).all(1) & (np.abs(ij0) < self._SPAN).all(1)
                & (np.abs(ij1) < self._SPAN).all(1))
        for k in np.flatnonzero(~fits):  # far outside any real map: the dict part takes them
            self.insert(int(rows[k]), centers_xyz[k], sizes_xyz[k])
        rows, ij0, ij1 = rows[fits], ij0[fits].astype(np.int64), ij1[fits].astype(np.int64)
        ni, nj = ij1[:, 0] - ij0[:, 0] + 1, ij1[:, 1] - ij0[:, 1] + 1
        count = ni * nj
        owner = np.repeat(np.arange(len(rows)), count)
        k = np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)  # cell number in its box
        i = ij0[owner, 0] + k // nj[owner]
        j = ij0[owner, 1] + k % nj[owner]
        codes = self._code(i, j)
        order = np.lexsort((rows[owner], codes))
        self.base_codes, self.base_rows = codes[order], rows[owner][order]
        self.base_live = np.zeros(int(rows.max()) + 1 if len(rows) else 0, bool)
        self.base_live[rows] = True

    def _code(self, i, j):
        return np.asarray(i, np.int64) * (1 << 32) + (np.asarray(j, np.int64) + self._SPAN)

    def insert(self, row: int, center, size) -> None:
        self.remove(row)
        cells = self._cells_of(center, size)
        for key in cells:
            self.cells[key].add(row)
        self.where[row] = cells

    def remove(self, row: int) -> None:
        if row < len(self.base_live):
            self.base_live[row] = False
        for key in self.where.pop(row, ()):
            bucket = self.cells.get(key)
            if bucket is not None:
                bucket.discard(row)
                if not bucket:
                    del self.cells[key]

    def query(self, xmin, xmax, ymin, ymax) -> np.ndarray:
        i0, i1 = int(np.floor(xmin / self.cell)), int(np.floor(xmax / self.cell))
        j0, j1 = int(np.floor(ymin / self.cell)), int(np.floor(ymax / self.cell))
        found: set = set()
        if self.cells:
            for i in range(i0, i1 + 1):
                for j in range(j0, j1 + 1):
                    bucket = self.cells.get((i, j))
                    if bucket:
                        found |= bucket
        parts = [np.fromiter(found, np.int64, len(found))]
        if len(self.base_codes):
            # Per grid column i, the cells j0..j1 are one run of codes.
            i = np.arange(max(i0, -self._SPAN + 1), min(i1, self._SPAN - 1) + 1)
            j0c, j1c = max(j0, -self._SPAN), min(j1, self._SPAN - 1)
            if len(i) and j0c <= j1c:
                lo = np.searchsorted(self.base_codes, self._code(i, j0c), "left")
                hi = np.searchsorted(self.base_codes, self._code(i, j1c), "right")
                n = hi - lo
                if n.sum():
                    at = np.repeat(lo - (np.cumsum(n) - n), n) + np.arange(int(n.sum()))
                    rows = self.base_rows[at]
                    parts.append(rows[self.base_live[rows]])
        # Sorted, so that the order of candidates (and so the map) never depends on set order.
        return np.unique(np.concatenate(parts))


@dataclass
class Event:
    session: int
    frame: int
    frame_key: str
    kind: str  # created | updated | merged | non-detection | removed
    object_id: int
    other_id: int = 0
    detail: str = ""


@dataclass
class SemanticMap:
    """Everything a map file holds, in memory."""

    classes: list[str]
    objects: ObjectTable
    up_rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    events: list[Event] = field(default_factory=list)
    sessions: list[dict] = field(default_factory=list)
    frame_keys: set = field(default_factory=set)
    created: str = ""
    # None: ``events`` is the whole log; a count: the map was loaded without its log (which then
    # holds this many events, on disk only).
    unread_events: int | None = None
    # With unread_events: the kinds whose events ``events`` does hold (all of them), or None.
    event_kinds: tuple | None = None

    @classmethod
    def new(cls, classes: list[str]) -> "SemanticMap":
        return cls(list(classes), ObjectTable(len(classes)))

    @property
    def class_vector_names(self) -> list[str]:
        return list(self.classes) + ["other"]

    @property
    def n_events(self) -> int:
        return len(self.events) if self.unread_events is None else self.unread_events

    def require_events(self, kind: str | None = None) -> None:
        """Raise RuntimeError when the event log (or, given ``kind``, its events of that kind) was
        not loaded (a bug in the caller: reading removals from an empty log, or saving a map that
        would lose its log)."""
        if self.unread_events is not None and (kind is None or kind not in (self.event_kinds or ())):
            raise RuntimeError("this map was loaded without its event log (load_map(events=False))")

    def active_rows(self) -> np.ndarray:
        return np.flatnonzero(self.objects.status == ACTIVE)

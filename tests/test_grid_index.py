"""The grid index built at once (numpy) answers every query exactly as the one-object-at-a-time
index did, also after inserts and removals mixed in; the reference below is that index."""

from __future__ import annotations

from collections import defaultdict

import numpy as np
import pytest

from ltc_cli.map.model import GridIndex


class LoopGridIndex:
    """The index as it was before GridIndex.build (a Python loop over objects): the reference."""

    def __init__(self, cell):
        self.cell = float(cell)
        self.cells = defaultdict(set)
        self.where = {}

    def _cells_of(self, center, size):
        r = 0.5 * float(np.hypot(size[0], size[1]))
        i0, i1 = int(np.floor((center[0] - r) / self.cell)), int(np.floor((center[0] + r) / self.cell))
        j0, j1 = int(np.floor((center[1] - r) / self.cell)), int(np.floor((center[1] + r) / self.cell))
        return [(i, j) for i in range(i0, i1 + 1) for j in range(j0, j1 + 1)]

    def insert(self, row, center, size):
        self.remove(row)
        cells = self._cells_of(center, size)
        for key in cells:
            self.cells[key].add(row)
        self.where[row] = cells

    def remove(self, row):
        for key in self.where.pop(row, ()):  # every cell listed in where holds the row
            self.cells[key].discard(row)
            if not self.cells[key]:
                del self.cells[key]

    def query(self, xmin, xmax, ymin, ymax):
        found = set()
        for i in range(int(np.floor(xmin / self.cell)), int(np.floor(xmax / self.cell)) + 1):
            for j in range(int(np.floor(ymin / self.cell)), int(np.floor(ymax / self.cell)) + 1):
                bucket = self.cells.get((i, j))
                if bucket:
                    found |= bucket
        return np.array(sorted(found), dtype=np.int64)


def random_boxes(rng, n, spread):
    centers = np.c_[rng.uniform(-spread, spread, (n, 2)), rng.uniform(0, 2, n)]
    # Sizes from tiny to several cells, some exactly on cell edges (integers with cell 2 / 0.5).
    sizes = np.where(rng.random((n, 3)) < 0.2, rng.integers(0, 5, (n, 3)).astype(float),
                     rng.uniform(0.01, 6.0, (n, 3)))
    return centers, sizes


def same_answers(a, b, rng, spread, n_queries=300):
    for _ in range(n_queries):
        x, y = rng.uniform(-spread * 1.2, spread * 1.2, 2)
        w, h = rng.uniform(0, spread / 3, 2)
        got, want = a.query(x - w, x + w, y - h, y + h), b.query(x - w, x + w, y - h, y + h)
        assert got.dtype == want.dtype == np.int64
        assert got.shape == want.shape and np.array_equal(got, want)


@pytest.mark.parametrize("cell,spread,seed", [(2.0, 40.0, 0), (0.5, 10.0, 1), (3.7, 300.0, 2)])
def test_build_answers_as_inserting_one_by_one(cell, spread, seed):
    rng = np.random.default_rng(seed)
    centers, sizes = random_boxes(rng, 2000, spread)
    # On-edge centres: integer multiples of the cell, where floor decides.
    centers[:200, :2] = cell * rng.integers(-5, 5, (200, 2))
    rows = np.sort(rng.choice(5000, 2000, replace=False))  # not every row is active
    new, old = GridIndex(cell), LoopGridIndex(cell)
    new.build(rows, centers, sizes)
    for r, c, s in zip(rows, centers, sizes):
        old.insert(int(r), c, s)
    same_answers(new, old, rng, spread)
    # A session then moves, adds and removes objects: both still agree.
    for _ in range(600):
        op = rng.random()
        row = int(rng.integers(0, 5200))
        if op < 0.4:
            c, s = np.r_[rng.uniform(-spread, spread, 2), 0.5], rng.uniform(0.05, 4, 3)
            new.insert(row, c, s)
            old.insert(row, c, s)
        else:
            new.remove(row)
            old.remove(row)
    same_answers(new, old, rng, spread)


def test_hand_worked_cells_and_edges():
    # cell 2: a 1 x 1 box (half-diagonal 0.7071) at (1, 1) spans x, y in [0.29, 1.71]: cell (0, 0)
    # only; a 2 x 0 box at (2, -1) has half-diagonal 1: x in [1, 3] -> i 0..1, y in [-2, 0] -> j -1..0.
    idx = GridIndex(2.0)
    idx.build([3, 7], [[1, 1, 0], [2, -1, 0]], [[1, 1, 1], [2, 0, 1]])
    assert idx.query(0, 0.1, 0, 0.1).tolist() == [3, 7]       # cell (0, 0): both
    assert idx.query(2.0, 2.1, -1.0, -0.9).tolist() == [7]    # cell (1, -1)
    assert idx.query(-4, -2.1, -4, -2.1).tolist() == []       # cell (-2, -2): nobody
    assert idx.query(-10, 10, -10, 10).tolist() == [3, 7]


def test_far_and_empty():
    idx, old = GridIndex(1.0), LoopGridIndex(1.0)
    centers = np.array([[1e12, 5.0, 0], [-3.0, 2.0, 0]])  # beyond the codes' range: the dict part
    sizes = np.array([[1.0, 1.0, 1.0], [0.5, 0.5, 0.5]])
    idx.build([0, 1], centers, sizes)
    for r in (0, 1):
        old.insert(r, centers[r], sizes[r])
    for box in [(1e12 - 1, 1e12 + 1, 4, 6), (-4, -2, 1, 3), (-10, 10, -10, 10)]:
        assert np.array_equal(idx.query(*box), old.query(*box))
    empty = GridIndex(2.0)
    empty.build(np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 3)))
    got = empty.query(-5, 5, -5, 5)
    assert got.dtype == np.int64 and got.shape == (0,)

"""Where a session looked: the floor-plan cells in which its depth saw something, kept in its session
row (``coverage``), so that ``ltc changes`` can tell an object added to a place the earlier visits saw
from one first seen in a place they never looked at (a room the robot had not entered yet).

Cells are ``cell`` metres square in the map's XY plane, keyed ``ix << 32 | iy`` (two's-complement
int32 halves). Pure numpy: :func:`seen_cells` from a frame's depth, :func:`footprint_cells` from a
box, and the text form of a set of keys (:func:`encode`, :func:`decode`). No I/O.
"""

from __future__ import annotations

import base64
import zlib

import numpy as np

from ltc_cli.types import Intrinsics

#: Metres: a cell is about a chair's seat; a room's floor plan is a few hundred of them.
CELL_M = 0.25
#: One depth reading in STEP x STEP pixels: at 640x480, 4800 a frame, ample for cells of 0.25 m.
#: An ingest reads those of stage 4's rays (``maintenance.ray_step``), which is all of the depth
#: that --dask workers send back (ingest/remote.pack_depth).
STEP = 8
_LOW = np.int64(0xFFFFFFFF)


def cell_keys(points_xy: np.ndarray, cell: float = CELL_M) -> np.ndarray:
    """Sorted unique keys (K,) int64 of the cells holding ``points_xy`` (N, 2), in metres."""
    ij = np.floor(np.asarray(points_xy, dtype=np.float64).reshape(-1, 2) / cell).astype(np.int64)
    return np.unique((ij[:, 0] << 32) | (ij[:, 1] & _LOW))


def key_cells(keys: np.ndarray) -> np.ndarray:
    """(K, 2) int64 cell indices (ix, iy) of ``keys``: the inverse of :func:`cell_keys`'s packing."""
    keys = np.asarray(keys, dtype=np.int64)
    iy = keys & _LOW
    return np.stack([keys >> 32, np.where(iy >= 2**31, iy - 2**32, iy)], axis=-1)


def seen_cells(depth_m: np.ndarray, T_map_camera: np.ndarray, intr: Intrinsics, depth_range: tuple[float, float],
               cell: float = CELL_M, step: int = STEP) -> np.ndarray:
    """Keys (K,) of the cells in which the depth image ``depth_m`` (H, W) has a reading within
    ``depth_range``, seen from ``T_map_camera`` (4, 4): the places this view saw, a floor, a table
    top or a wall. Readings beyond the range are too sparse to say a place was seen."""
    from ltc_cli.geometry.camera import backproject, transform  # scipy: not for ltc info's start-up

    # The pixels of pipeline/visibility.ray_grid's rays, one in each step x step block.
    v, u = np.meshgrid(np.arange(step / 2 - 0.5, depth_m.shape[0], step).astype(int),
                       np.arange(step / 2 - 0.5, depth_m.shape[1], step).astype(int), indexing="ij")
    z = depth_m[v, u]
    ok = (z >= depth_range[0]) & (z <= depth_range[1])
    points_map = transform(T_map_camera, backproject(u[ok], v[ok], z[ok], intr))
    return cell_keys(points_map[:, :2], cell)


def footprint_cells(center: np.ndarray, yaw: float, size: np.ndarray, cell: float = CELL_M) -> np.ndarray:
    """Keys of the cells under a box's footprint (center (3,), yaw, size (3,)): the cells of points
    spread over it at most half a cell apart, edges included."""
    half = np.asarray(size[:2], dtype=np.float64) / 2
    n = np.maximum(np.ceil(2 * half / (cell / 2)).astype(int) + 1, 2)
    a, b = np.meshgrid(np.linspace(-half[0], half[0], n[0]), np.linspace(-half[1], half[1], n[1]))
    c, s = np.cos(yaw), np.sin(yaw)
    xy = np.stack([center[0] + c * a - s * b, center[1] + s * a + c * b], axis=-1)
    return cell_keys(xy.reshape(-1, 2), cell)


def encode(keys: np.ndarray, cell: float = CELL_M) -> str:
    """``keys`` as text: the cell size, a colon, and the sorted keys' differences, deflated, base64."""
    keys = np.unique(np.asarray(keys, dtype=np.int64))
    deltas = np.diff(keys, prepend=np.int64(0)).astype("<i8")
    return f"{cell:g}:" + base64.b64encode(zlib.compress(deltas.tobytes(), 6)).decode("ascii")


def decode(text: str) -> tuple[np.ndarray, float]:
    """(keys (K,) int64, cell size) of :func:`encode`'s text; ValueError for anything else."""
    head, sep, body = str(text).partition(":")
    if not sep:
        raise ValueError("no cell size")
    cell = float(head)
    if not (np.isfinite(cell) and cell > 0):
        raise ValueError(f"cell size {head!r}")
    try:
        raw = zlib.decompress(base64.b64decode(body.encode("ascii"), validate=True))
    except (zlib.error, ValueError) as exc:
        raise ValueError(f"cells: {exc}") from None
    if len(raw) % 8:
        raise ValueError("cells: truncated")
    return np.cumsum(np.frombuffer(raw, dtype="<i8").astype(np.int64)), cell


def sessions_seen(rows: list[dict], strict: bool = True) -> tuple[np.ndarray, float] | None:
    """(keys (K,), cell size): the cells the session ``rows`` saw together. None when none of them
    kept any, when they used other cell sizes, or (``strict``) when one of them kept none (written
    by an older ltc): a part of what they saw would pass for all of it."""
    keys, cells = [], set()
    for row in rows:
        try:
            got, cell = decode(row.get("coverage") or "")
        except ValueError:
            if strict:
                return None
            continue
        keys.append(got)
        cells.add(cell)
    if len(cells) != 1:
        return None
    return np.unique(np.concatenate(keys)), cells.pop()


def seen_area(text: str) -> float | None:
    """Square metres of floor plan a session's ``coverage`` text says it saw; None when it kept none."""
    try:
        keys, cell = decode(text)
    except ValueError:
        return None
    return len(keys) * cell * cell


class Coverage:
    """The cells one session saw, grown frame by frame and kept as text in its row."""

    def __init__(self, keys: np.ndarray | None = None, cell: float = CELL_M, step: int = STEP, known: bool = True):
        self.cell, self.step, self.known = cell, step, known
        self.keys: set[int] = set() if keys is None else set(np.asarray(keys, dtype=np.int64).tolist())

    @classmethod
    def resumed(cls, text: str, step: int = STEP, frames_done: int = 0) -> Coverage:
        """The coverage a session's row kept (an interrupted run's), or an empty one for a session
        that mapped nothing yet. A session that mapped frames and kept no coverage (an older ltc's,
        resumed) stays unknown: what it saw before is not known, and a part would pass for all."""
        try:
            keys, cell = decode(text)
        except ValueError:
            return cls(step=step, known=not frames_done)
        return cls(keys, cell, step)

    def add(self, depth_m: np.ndarray, T_map_camera: np.ndarray, intr: Intrinsics,
            depth_range: tuple[float, float]) -> None:
        if self.known:
            self.keys.update(seen_cells(depth_m, T_map_camera, intr, depth_range, self.cell, self.step).tolist())

    def text(self) -> str:
        """:func:`encode`'s text of the cells; "" when unknown."""
        if not self.known:
            return ""
        return encode(np.fromiter(self.keys, dtype=np.int64, count=len(self.keys)), self.cell)

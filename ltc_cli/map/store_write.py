"""Writing a map's HDF5 file (the map store's other half; store.py reads, locks and commits).

Two ways, one result: :func:`map_image` builds the whole file in memory; :func:`write_changes`
writes into an open file that this process committed only what changed since (new events and
frame keys, changed session rows, the chunks of the object columns that hold a changed row).
Every per-row dataset is chunked and resizable (``maxshape=(None, ...)``), so appending rewrites
at most the last chunk; a text dataset that needs a wider fixed width is recreated whole. The file
keeps its free-space records (``fs_persist``), so a recreated dataset reuses the space the old one
freed; when the free space passes half the file, :func:`write_changes` declines and the caller
writes the whole file again (compaction). Loading either file gives the same map; the frames
dataset holds the same keys, in commit order after an in-place commit (sorted after a whole one).
"""

from __future__ import annotations

import copy
import itertools
import json
import os
import weakref
from dataclasses import dataclass

import h5py
import numpy as np

from ltc_cli import __version__
from ltc_cli.map import journal
from ltc_cli.map.integrity import EVENT_INT, EVENT_TEXT
from ltc_cli.map.model import SemanticMap

FORMAT = "ltc-map"
VERSION = 1
# Session rows: column -> kind ("s" text, "i" integer, "f" float). Dicts and lists are JSON text.
SESSION_COLUMNS = {
    "started": "s", "finished": "s", "status": "s", "sources": "s", "recordings": "s",
    "readers": "s", "detector": "s", "metric": "s", "policy": "s", "settings": "s", "v_other": "f",
    "ltc_version": "s", "frames_done": "i", "frames_skipped": "i", "up_rotation": "s", "floor_z": "s",
    "visit": "i",  # 1 for a recording's first ingest, n for its n-th (--revisit); 0 in older maps
    "cameras": "s",  # per recording: size, fx fy cx cy, the reader's calibration name; "" in older maps
    "frames_still": "i",  # frames not mapped: the camera had not moved (ingest/keyframes.py); 0 in older maps
    "still_refs": "s",  # per recording, the last mapped pose (JSON), that a resumed session goes on from
    "reader_options": "s",  # the reader options the ingest was given (-r, JSON), to read it again so; "" in older maps
    "frames": "s",  # the range of the recordings' frames mapped (--frames); "" for all, and in older maps
    "coverage": "s",  # the floor-plan cells the session's depth saw (map/coverage.py); "" in older maps
}
# Checksummed metadata (libver v108); free-space records kept in the file, so freed space is reused.
FILE_OPTIONS = {"libver": ("v108", "latest"), "fs_strategy": "fsm", "fs_persist": True, "fs_threshold": 1}
CHUNK_BYTES = 1 << 16  # a chunk's target size: an append rewrites at most this much per column
_images = itertools.count()


def chunk_rows(n_rows: int, row_bytes: int) -> int:
    """Rows per chunk for a dataset of n_rows: about a quarter of it (small maps stay small),
    at least 16 rows, at most CHUNK_BYTES."""
    return max(16, min(CHUNK_BYTES // max(row_bytes, 1), 1 << (max(n_rows, 1) // 4).bit_length()))


def text_array(values: list[str]) -> np.ndarray:
    """Text as fixed-length UTF-8 (NUL-padded): no global heap, whose damage made HDF5 loop for
    ever on reading; the rest of the file's metadata is checksummed (libver v108)."""
    raw = [v.encode("utf-8") for v in values]
    width = max([len(b) for b in raw] + [1])
    return np.array(raw, dtype=h5py.string_dtype("utf-8", width))


def _column(group, name: str, data: np.ndarray) -> None:
    """A per-row dataset: contiguous while under CHUNK_BYTES (rewritten whole when it changes),
    else chunked and resizable. A chunked dataset costs a B-tree node of about 2.5 KB (libver v108),
    which would make a small map's file several times larger."""
    if data.nbytes < CHUNK_BYTES:
        group.create_dataset(name, data=data, dtype=data.dtype)
        return
    row_bytes = data.dtype.itemsize * int(np.prod(data.shape[1:], dtype=np.int64))
    group.create_dataset(name, data=data, dtype=data.dtype, maxshape=(None,) + data.shape[1:],
                         chunks=(chunk_rows(len(data), row_bytes),) + data.shape[1:])


def _event_column(events, k: str) -> np.ndarray:
    values = [getattr(e, k) for e in events]
    return text_array(values) if k in EVENT_TEXT else np.array(values, dtype=np.int64)


def _session_column(rows: list[dict], key: str, kind: str) -> np.ndarray:
    # A row made before a column existed stores it empty, as load_map reads it.
    vals = [s.get(key, "" if kind == "s" else 0) for s in rows]
    if kind == "s":
        return text_array([v if isinstance(v, str) else json.dumps(v) for v in vals])
    return np.array(vals, dtype=np.int64 if kind == "i" else np.float64)


def _object_columns(smap: SemanticMap) -> dict:
    return {"id": smap.objects.ids, **smap.objects.columns()}


def map_image(smap: SemanticMap) -> bytes:
    """The whole map as the bytes of an HDF5 file, built in memory."""
    smap.require_events()
    name = f"ltc-map-{os.getpid()}-{next(_images)}.h5"
    with h5py.File(name, "w", driver="core", backing_store=False, **FILE_OPTIONS) as f:
        # Text attributes fixed-length too (np.bytes_), for the reason text_array gives, the format
        # mark included: every ltc reader of version 1 decodes a bytes mark, and a variable-length
        # one was the file's last global heap (a damaged heap made HDF5 loop for ever on it).
        f.attrs["format"] = np.bytes_(FORMAT)
        f.attrs["format_version"] = VERSION
        f.attrs["ltc_version"] = np.bytes_(__version__)
        f.attrs["created"] = np.bytes_(smap.created.encode("utf-8"))
        f.attrs["description"] = np.bytes_(
            "ltc object map: Z-oriented boxes (center, yaw about z, size), class vectors over "
            "classes + other, in a z-up map frame; see the ltc DESIGN, section 4"
        )
        f.create_dataset("classes", data=text_array(smap.classes))
        f.create_dataset("up_rotation", data=np.asarray(smap.up_rotation, dtype=np.float64))
        og = f.create_group("objects")
        for name, arr in _object_columns(smap).items():
            _column(og, name, arr)
        eg = f.create_group("events")
        for k in EVENT_INT + EVENT_TEXT:
            _column(eg, k, _event_column(smap.events, k))
        sg = f.create_group("sessions")
        for key, kind in SESSION_COLUMNS.items():
            _column(sg, key, _session_column(smap.sessions, key, kind))
        _column(f, "frames", text_array(sorted(smap.frame_keys)))
        f.flush()
        return f.id.get_file_image()


@dataclass
class Committed:
    """What a process last committed to a map file: enough to write only what changed since."""
    ident: tuple  # (device, inode, size, mtime ns) of the file right after the commit
    smap: weakref.ref
    classes: list
    created: str
    up_rotation: np.ndarray
    n_events: int
    frames: set
    sessions: list
    objects: dict


def committed(smap: SemanticMap, ident: tuple) -> Committed:
    return Committed(ident, weakref.ref(smap), list(smap.classes), smap.created,
                     np.array(smap.up_rotation, dtype=np.float64), len(smap.events), set(smap.frame_keys),
                     copy.deepcopy(smap.sessions), {k: v.copy() for k, v in _object_columns(smap).items()})


class _Rewrite(Exception):
    """The change does not fit the file as laid out: write the whole file instead."""


def _put(group, name: str, rows: np.ndarray, start: int, whole) -> None:
    """Rows ``start:`` of dataset ``name`` become ``rows`` (its length start + len(rows)); a
    text column too narrow for them is recreated from ``whole()``."""
    ds = group[name]
    n = start + len(rows)
    if n == ds.shape[0] and not len(rows):
        return
    if ds.chunks is None or (ds.dtype.kind == "S" and rows.dtype.itemsize > ds.dtype.itemsize):
        del group[name]  # small, or text that needs a wider width: written anew
        _column(group, name, whole())
        return
    if n > 256 * ds.chunks[0] and ds.chunks[0] * ds.dtype.itemsize < CHUNK_BYTES // 2:
        raise _Rewrite  # chunks now far too small for its length
    if n != ds.shape[0]:
        ds.resize((n,) + ds.shape[1:])
    if len(rows):
        ds[start:n] = rows


def _changed_rows(old: np.ndarray, new: np.ndarray) -> np.ndarray:
    """Rows whose bytes differ (so -0.0 against 0.0 counts, and NaN against NaN does not)."""
    if not len(old):
        return np.zeros(0, np.int64)
    a, b = (np.ascontiguousarray(x).reshape(len(x), -1).view(np.uint8) for x in (old, new))
    return np.flatnonzero((a != b).any(axis=1))


def _write_objects(og, smap: SemanticMap, rec: Committed) -> None:
    for name, arr in _object_columns(smap).items():
        old = rec.objects[name]
        n_old = len(old)
        ds = og[name]
        changed = _changed_rows(old, arr[:n_old])
        if ds.chunks is None:
            if changed.size or len(arr) > n_old:
                _put(og, name, arr, 0, lambda a=arr: a)
            continue
        chunk = ds.chunks[0]
        for c in np.unique(changed // chunk).tolist():  # whole chunks: one write each
            lo, hi = c * chunk, min((c + 1) * chunk, n_old)
            ds[lo:hi] = arr[lo:hi]
        _put(og, name, arr[n_old:], n_old, lambda a=arr: a)


def write_changes(f: h5py.File, smap: SemanticMap, rec: Committed) -> bool:
    """Write into ``f`` (the file ``rec`` describes) what changed in ``smap`` since; False when
    the whole file must be written instead (nothing in ``f`` is then worth keeping)."""
    smap.require_events()
    fewer = rec.frames - smap.frame_keys or len(smap.events) < rec.n_events or len(smap.sessions) < len(rec.sessions)
    if fewer or list(smap.classes) != rec.classes or smap.objects.n < len(rec.objects["id"]):
        return False
    if 2 * f.id.get_freespace() > f.id.get_filesize():
        return False  # compaction: half the file unused
    try:
        eg, sg = f["events"], f["sessions"]
        new_events = smap.events[rec.n_events:]
        for k in EVENT_INT + EVENT_TEXT:
            _put(eg, k, _event_column(new_events, k), rec.n_events, lambda k=k: _event_column(smap.events, k))
        first = next((i for i, (a, b) in enumerate(zip(rec.sessions, smap.sessions)) if a != b), len(rec.sessions))
        for key, kind in SESSION_COLUMNS.items():
            if first < len(smap.sessions):
                _put(sg, key, _session_column(smap.sessions[first:], key, kind), first,
                     lambda key=key, kind=kind: _session_column(smap.sessions, key, kind))
        new_keys = sorted(smap.frame_keys - rec.frames)
        _put(f, "frames", text_array(new_keys), len(rec.frames), lambda: text_array(sorted(smap.frame_keys)))
        _write_objects(f["objects"], smap, rec)
    except _Rewrite:
        return False
    if not np.array_equal(f["up_rotation"][()], smap.up_rotation):
        f["up_rotation"][...] = np.asarray(smap.up_rotation, dtype=np.float64)
    if smap.created != rec.created:
        f.attrs["created"] = np.bytes_(smap.created.encode("utf-8"))
    if f.attrs.get("ltc_version") != np.bytes_(__version__):
        f.attrs["ltc_version"] = np.bytes_(__version__)
    return True


def file_ident(st: os.stat_result) -> tuple:
    return st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns


def path_ident(path) -> tuple | None:
    """file_ident of the file at ``path`` now, or None when there is none."""
    try:
        return file_ident(os.stat(path))
    except OSError:
        return None


def commit_in_place(smap: SemanticMap, path, rec: Committed) -> bool:
    """Commit to map file ``path`` only what changed since ``rec``: HDF5 writes into a
    journal.Overlay of the file, journal.commit writes the result in place. False, with nothing
    written, when the whole file must be written instead. Raises OSError (NoSpaceError for a
    full disk) with the file as it was (``rec.ident`` updated) or, if even the rollback failed,
    with its journal left for journal.recover."""
    try:
        fd = os.open(path, os.O_RDWR | os.O_CLOEXEC)
    except OSError:
        return False  # the whole commit says what is wrong
    try:
        st = os.fstat(fd)
        if file_ident(st) != rec.ident:
            return False  # changed since this process committed it
        view = journal.Overlay(fd, st.st_size)
        try:
            with h5py.File(view, "r+") as f:
                if not write_changes(f, smap, rec):
                    return False
        except (OSError, ValueError, KeyError, TypeError, RuntimeError):  # only the overlay was written
            return False
        try:
            journal.commit(path, fd, st.st_size, view.changes(), view.length)
        finally:
            if not journal.journal_path(path).exists():  # committed, or rolled back
                rec.ident = file_ident(os.fstat(fd))
        return True
    finally:
        os.close(fd)

"""The map store: the only code that touches HDF5.

One ``.h5`` file holds the whole map (DESIGN.md section 4); h5dump shows all of it, nothing is
pickled. Every save writes a complete new file beside the old one, flushes and fsyncs it and then
``os.replace``-s it over the old one, so a reader (or a crash) only ever sees a whole map.
"""

from __future__ import annotations

import errno
import fcntl
import json
import os
from pathlib import Path

import h5py
import numpy as np

from ltc_cli import __version__
from ltc_cli.errors import LtcError, MapFormatError, MapLockedError
from ltc_cli.fileio import atomic_target
from ltc_cli.map.model import ADDED_COLUMNS, COLUMNS, Event, ObjectTable, SemanticMap

FORMAT = "ltc-map"
VERSION = 1

_STR = h5py.string_dtype(encoding="utf-8")
_EVENT_STR = ("frame_key", "kind", "detail")
_EVENT_INT = ("session", "frame", "object_id", "other_id")
# Session rows: column -> kind ("s" text, "i" integer, "f" float). Dicts and lists are JSON text.
SESSION_COLUMNS = {
    "started": "s", "finished": "s", "status": "s", "sources": "s", "recordings": "s",
    "readers": "s", "detector": "s", "metric": "s", "policy": "s", "settings": "s", "v_other": "f",
    "ltc_version": "s", "frames_done": "i", "frames_skipped": "i", "up_rotation": "s", "floor_z": "s",
    "visit": "i",  # 1 for a recording's first ingest, n for its n-th (--revisit); 0 in older maps
}


class MapLock:
    """An exclusive advisory lock (flock on ``MAP.h5.lock``) held while a process writes a map.

    The kernel drops the lock when the holder dies, even by SIGKILL, so a crash never leaves a map
    locked for ever.
    """

    def __init__(self, path):
        self.path = Path(str(path) + ".lock")
        self.map_path = Path(path)
        self.fd = None

    def acquire(self) -> "MapLock":
        if not self.map_path.parent.is_dir():
            raise LtcError("the map's folder does not exist", self.map_path)
        try:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as exc:
            raise MapLockedError(f"cannot create lock file ({exc.strerror})", self.path) from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            holder = ""
            try:
                holder = os.pread(fd, 64, 0).decode().strip()
            except OSError:
                pass
            os.close(fd)
            if exc.errno in (errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK):
                who = f" (pid {holder})" if holder else ""
                raise MapLockedError(f"another ltc process{who} is writing this map; try again when it ends",
                                     self.map_path) from None
            raise
        os.ftruncate(fd, 0)
        os.pwrite(fd, str(os.getpid()).encode(), 0)
        self.fd = fd
        return self

    def release(self) -> None:
        if self.fd is not None:
            fcntl.flock(self.fd, fcntl.LOCK_UN)
            os.close(self.fd)
            self.fd = None

    def __enter__(self):
        return self.acquire()

    def __exit__(self, *exc):
        self.release()


def check_map_file(path) -> None:
    """Raise MapFormatError unless ``path`` is an ltc map this version can read."""
    _open_checked(Path(path)).close()


def _open_checked(path: Path) -> h5py.File:
    if not path.is_file():
        raise MapFormatError("map file does not exist", path)
    try:
        f = h5py.File(path, "r")
    except OSError:
        raise MapFormatError("not an ltc map (not an HDF5 file)", path) from None
    fmt = f.attrs.get("format")
    if isinstance(fmt, bytes):
        fmt = fmt.decode()
    if fmt != FORMAT:
        f.close()
        raise MapFormatError("not an ltc map (an HDF5 file without the ltc-map format mark)", path)
    version = int(f.attrs.get("format_version", -1))
    if version > VERSION:
        f.close()
        raise MapFormatError(
            f"map format version {version} is newer than this ltc reads ({VERSION}); upgrade ltc", path
        )
    if version < 1:
        f.close()
        raise MapFormatError(f"map format version {version} is not valid", path)
    return f


def _text(arr) -> list[str]:
    return [v.decode() if isinstance(v, bytes) else str(v) for v in arr]


def load_map(path) -> SemanticMap:
    """Read a whole map. Raises MapFormatError for files that are not maps or are too new."""
    path = Path(path)
    f = _open_checked(path)
    try:
        classes = _text(f["classes"][()])
        og = f["objects"]
        cols = {name: og[name][()] for name in list(COLUMNS) + ["scores"] if name in og or name not in ADDED_COLUMNS}
        if cols["scores"].ndim != 2 or cols["scores"].shape[1] != len(classes) + 1:
            raise MapFormatError("objects/scores does not match the class list", path)
        table = ObjectTable.from_columns(cols)
        eg = f["events"]
        n_ev = len(eg["kind"])
        ev_cols = {k: _text(eg[k][()]) for k in _EVENT_STR}
        ev_cols.update({k: eg[k][()].tolist() for k in _EVENT_INT})
        events = [Event(**{k: ev_cols[k][i] for k in _EVENT_STR + _EVENT_INT}) for i in range(n_ev)]
        sg = f["sessions"]
        sessions = []
        n_s = len(sg["started"]) if "started" in sg else 0
        for i in range(n_s):
            row = {}
            for key, kind in SESSION_COLUMNS.items():
                if key not in sg:  # a column newer than the file: empty
                    row[key] = "" if kind == "s" else 0
                    continue
                v = sg[key][i]
                row[key] = (v.decode() if isinstance(v, bytes) else str(v)) if kind == "s" else (
                    int(v) if kind == "i" else float(v))
            sessions.append(row)
        keys = set(_text(f["frames"][()]))
        smap = SemanticMap(
            classes=classes, objects=table, up_rotation=np.array(f["up_rotation"][()]),
            events=events, sessions=sessions, frame_keys=keys,
            created=str(f.attrs.get("created", "")),
        )
    except KeyError as exc:
        raise MapFormatError(f"damaged ltc map (missing {exc.args[0]})", path) from None
    finally:
        f.close()
    return smap


def save_map(smap: SemanticMap, path) -> None:
    """Write the whole map atomically: a temporary file beside it, fsync, then os.replace."""
    path = Path(path)
    with atomic_target(path) as tmp, h5py.File(tmp, "w") as f:
        f.attrs["format"] = FORMAT
        f.attrs["format_version"] = VERSION
        f.attrs["ltc_version"] = __version__
        f.attrs["created"] = smap.created
        f.attrs["description"] = (
            "ltc object map: Z-oriented boxes (center, yaw about z, size), class vectors over "
            "classes + other, in a z-up map frame; see the ltc DESIGN, section 4"
        )
        f.create_dataset("classes", data=np.array(smap.classes, dtype=object), dtype=_STR)
        f.create_dataset("up_rotation", data=np.asarray(smap.up_rotation, dtype=np.float64))
        og = f.create_group("objects")
        og.create_dataset("id", data=smap.objects.ids)
        for name, arr in smap.objects.columns().items():
            og.create_dataset(name, data=arr)
        eg = f.create_group("events")
        ev = smap.events
        for k in _EVENT_INT:
            eg.create_dataset(k, data=np.array([getattr(e, k) for e in ev], dtype=np.int64))
        for k in _EVENT_STR:
            eg.create_dataset(k, data=np.array([getattr(e, k) for e in ev], dtype=object), dtype=_STR)
        sg = f.create_group("sessions")
        for key, kind in SESSION_COLUMNS.items():
            vals = [s.get(key, "" if kind == "s" else 0) for s in smap.sessions]  # rows made before a column: empty
            if kind == "s":
                vals = [v if isinstance(v, str) else json.dumps(v) for v in vals]
                sg.create_dataset(key, data=np.array(vals, dtype=object), dtype=_STR)
            else:
                sg.create_dataset(key, data=np.array(vals, dtype=np.int64 if kind == "i" else np.float64))
        f.create_dataset("frames", data=np.array(sorted(smap.frame_keys), dtype=object), dtype=_STR)
        f.flush()

"""The map store: the only code that touches HDF5 (with store_write.py, which writes the file).

One ``.h5`` file holds the whole map (DESIGN.md section 4); h5dump shows all of it, nothing is
pickled. HDF5 itself never writes to disk: a full disk in the middle of an HDF5 flush crashed the
process (h5py segfaults there), a plain ``os.write`` just fails. A commit is one of two kinds:

* in place, when the file is the one this map was read from or last committed to, unchanged
  since: HDF5 writes only what changed into an in-memory overlay of the file, and journal.py
  writes those bytes in place behind a rollback journal (its docstring says how a crash is undone);
* whole (a new map, a file changed by another process since, a change that does not fit the
  file's layout, or a file half unused space): the
  complete new file is built in memory, checked for space, written beside the old one, fsync-ed
  and ``os.replace``-d over it.

Either way a reader (or a crash, or a full disk) only ever sees a whole commit: readers hold the
map file's lock shared, and roll back (or read around) the journal of a writer that died.

Every path to a map (symlinks included) is one map: the lock and the commit use the resolved path,
so two writers on ``link.h5 -> real.h5`` and ``real.h5`` exclude each other, and a symlinked map
stays a symlink to its updated target. docs/reliability.md lists every fault tried.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
from pathlib import Path

import h5py
import numpy as np

from ltc_cli.errors import MapFormatError, MapWriteError
from ltc_cli.fileio import NoSpaceError, free_bytes, write_bytes_atomic
from ltc_cli.map import journal
from ltc_cli.map.lock import (MapLock, check_writable, folder_not_writable, mb, no_space, orphan_temp_files,
                              resolve_map_path)
from ltc_cli.map.integrity import EVENT_INT, EVENT_TEXT, REQUIRED, check_map_arrays, check_sessions
from ltc_cli.map.model import ADDED_COLUMNS, COLUMNS, Event, ObjectTable, SemanticMap
from ltc_cli.map.store_write import (FORMAT, SESSION_COLUMNS, VERSION, commit_in_place, committed, file_ident,
                                    map_image, path_ident)

__all__ = ["FORMAT", "VERSION", "SESSION_COLUMNS", "MapLock", "load_map", "load_sessions", "save_map", "map_image",
           "check_map_file", "check_writable", "orphan_temp_files", "resolve_map_path"]
_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
_read_ident: dict = {}  # resolved path -> file_ident of the file load_map just read there
# (resolved path, id of the SemanticMap) -> store_write.Committed: the file as that map last
# committed or read it. Several maps may hold one; the first to commit changes the file's
# identity, and the others' records no longer match it (they rewrite).
_committed: dict = {}


def check_map_file(path) -> None:
    """Raise MapFormatError unless ``path`` is a whole ltc map this version can read."""
    load_map(path)


def _damaged(what: str, path) -> MapFormatError:
    return MapFormatError(f"damaged ltc map: {what}; ltc will not write over it", path)


def _truncated(path) -> MapFormatError:
    return MapFormatError("the map file is truncated or damaged (an HDF5 file that cannot be read whole); ltc will "
                          "not write over it", path)


def _looks_like_hdf5(path: Path) -> bool:
    # The signature is at 0 or, after a user block, at 512, 1024, 2048, ...
    with open(path, "rb") as fh:
        offset = 0
        while True:
            fh.seek(offset)
            head = fh.read(8)
            if head == _HDF5_SIGNATURE:
                return True
            if len(head) < 8:
                return False
            offset = 512 if offset == 0 else offset * 2


@contextlib.contextmanager
def _reading(path: Path):
    """Hold the map file's lock shared (an in-place commit waits for it) once any journal of a
    dead writer is rolled back; yield what to open: the path or, where the map cannot be written
    (a read-only folder), an in-memory view of the map as its journal restores it."""
    real = resolve_map_path(path)  # the journal is beside the file a symlink names
    if not real.is_file():
        yield path
        return
    with contextlib.suppress(OSError):
        journal.recover(real)
    try:
        fd = os.open(real, os.O_RDONLY | os.O_CLOEXEC)
    except OSError:
        yield path  # _open_checked names the problem
        return
    try:
        fcntl.flock(fd, fcntl.LOCK_SH)
        try:
            view = journal.rolled_back_view(fd, os.fstat(fd).st_size, journal.journal_path(real))
        except OSError:
            view = None
        yield path if view is None else view
        if view is None:
            _read_ident[str(real)] = file_ident(os.fstat(fd))
    finally:
        os.close(fd)


def _open_checked(path: Path, source) -> h5py.File:
    if not path.exists():
        raise MapFormatError("map file does not exist", path)
    if not path.is_file():
        raise MapFormatError("not an ltc map (not a file)", path)
    try:
        hdf5 = source is not path or _looks_like_hdf5(path)
    except OSError as exc:
        raise MapFormatError(f"cannot read the map file ({exc.strerror})", path) from None
    if not hdf5:
        raise MapFormatError("not an ltc map (not an HDF5 file)", path)
    try:
        f = h5py.File(source, "r")
    except OSError:
        raise _truncated(path) from None
    try:
        fmt = f.attrs.get("format")
        if isinstance(fmt, bytes):
            fmt = fmt.decode()
        if fmt != FORMAT:
            raise MapFormatError("not an ltc map (an HDF5 file without the ltc-map format mark)", path)
        version = f.attrs.get("format_version")
        if version is None:
            raise _damaged("it has no format_version", path)
        if isinstance(version, (bool, np.bool_)) or not isinstance(version, (int, np.integer)):
            raise _damaged(f"format_version is {version!r}, not an integer", path)
        if version > VERSION:
            raise MapFormatError(
                f"map format version {version} is newer than this ltc reads ({VERSION}); upgrade ltc", path
            )
        if version < 1:
            raise _damaged(f"format_version {version} is not a valid version", path)
    except (OSError, KeyError, ValueError, TypeError, RuntimeError):  # HDF5 errors in damaged metadata
        f.close()
        raise _truncated(path) from None
    except BaseException:
        f.close()
        raise
    return f


def _attr_text(f: h5py.File, name: str, path: Path) -> str:
    try:
        value = f.attrs.get(name, "")
    except (OSError, KeyError, ValueError, TypeError, RuntimeError):
        raise _truncated(path) from None
    try:
        return value.decode() if isinstance(value, bytes) else str(value)
    except UnicodeDecodeError:
        raise _damaged(f"the attribute {name} is not UTF-8 text", path) from None


def _text(arr) -> list[str]:
    return [v.decode() if isinstance(v, bytes) else str(v) for v in arr]


def _member(f: h5py.File, name: str, kind, path: Path):
    """The dataset or group ``name``; a missing one is named in plain words. A member that is
    listed but cannot be opened is damage, not absence."""
    parent, _, leaf = name.rpartition("/")
    group = _member(f, parent, h5py.Group, path) if parent else f
    what = "group" if kind is h5py.Group else "dataset"
    if leaf not in group:
        raise _damaged(f"the {what} {name} is missing", path)
    obj = group[leaf]
    if not isinstance(obj, kind):
        raise _damaged(f"{name} is not a {what}", path)
    return obj


def _read_arrays(f: h5py.File, path: Path, events: bool | tuple = True) -> tuple[dict, dict, int]:
    """Every dataset of the map, read whole (the event log's only with ``events``; a tuple of
    kinds keeps only their events, undecoded text dropped first), and the log's length."""
    try:
        data = {name: _read_or_shape(_member(f, name, h5py.Dataset, path), events or not name.startswith("events/"))
                for name in REQUIRED}
        # Object columns newer than the file are absent (read as zeros); present ones are checked.
        og = f["objects"]
        data.update({f"objects/{name}": np.asarray(og[name][()]) for name in ADDED_COLUMNS if name in og})
        sg = _member(f, "sessions", h5py.Group, path)
        # A column newer than the file is absent (read as empty); the others must agree.
        sessions = {k: np.asarray(_member(sg, k, h5py.Dataset, path)[()]) for k in SESSION_COLUMNS if k in sg}
    except (OSError, KeyError, ValueError, TypeError, RuntimeError):  # HDF5 errors in damaged data
        raise _truncated(path) from None
    n_events = _keep_event_kinds(data, events) if isinstance(events, tuple) else len(data["events/kind"])
    _decode_text(data, "", path)
    _decode_text(sessions, "sessions/", path)
    return data, sessions, n_events


def _keep_event_kinds(data: dict, kinds: tuple) -> int:
    """The event columns' rows of these kinds only, in place; columns of unequal lengths or not
    1-D (damage) are left whole for check_map_arrays to name. The other rows' text is never decoded: most of the
    cost of reading a long log."""
    names = [f"events/{k}" for k in EVENT_INT + EVENT_TEXT]
    n = len(data["events/kind"])
    if any(data[name].ndim != 1 or len(data[name]) != n for name in names):
        return n
    raw = data["events/kind"]
    keep = np.isin(raw, [k.encode() for k in kinds] if raw.dtype.kind in "SO" else list(kinds))
    for name in names:
        data[name] = data[name][keep]
    return n


def _read_or_shape(ds: h5py.Dataset, read: bool) -> np.ndarray:
    """The dataset's values, or (``read`` False) an array of its shape and kind that holds none
    (no memory): enough for the checks of kind and length. Text stands in as str (no decoding)."""
    return np.asarray(ds[()]) if read else np.broadcast_to(
        np.zeros((), "U1" if h5py.check_string_dtype(ds.dtype) else ds.dtype), ds.shape)


def _decode_text(arrays: dict, prefix: str, path: Path) -> None:
    """Text datasets (fixed-length or variable-length UTF-8) -> object arrays of str, in place."""
    for name, arr in list(arrays.items()):
        if arr.dtype.kind in "OS" and arr.ndim == 1:
            try:
                arrays[name] = np.array([v.decode() if isinstance(v, bytes) else v for v in arr], dtype=object)
            except UnicodeDecodeError:
                raise _damaged(f"{prefix}{name} holds text that is not UTF-8", path) from None


def load_map(path, events: bool | tuple = True) -> SemanticMap:
    """Read a whole map. Raises MapFormatError for files that are not maps, are too new, or are
    damaged (docs/reliability.md). ``events=False`` leaves the event log on disk (1.5M events:
    4.6 s, 900 MiB) but checks all but its contents; ``n_events`` counts it; such a map cannot be
    saved. ``events=("removed",)`` loads only the events of those kinds (``event_kinds``); such a
    map cannot be saved either."""
    path = Path(path)
    with _reading(path) as source:
        f = _open_checked(path, source)
        try:
            data, sess, n_all = _read_arrays(f, path, events)
            created = _attr_text(f, "created", path)
            # Only a file that keeps its free-space records can be patched: in one without (maps
            # of ltc before commits in place) every rewritten dataset's old space would be lost.
            patchable = bool(f.id.get_create_plist().get_file_space_strategy()[1])
        finally:
            f.close()
    problem = check_map_arrays(data, sess, SESSION_COLUMNS)
    if problem:
        raise _damaged(problem, path)
    classes = _text(data["classes"])
    cols = {name: data[f"objects/{name}"] for name in list(COLUMNS) + ["scores"] if f"objects/{name}" in data}
    table = ObjectTable.from_columns(cols)
    log, unread = [], len(data["events/kind"])
    if events:
        ev = {k: _text(data[f"events/{k}"]) for k in EVENT_TEXT}
        ev.update({k: data[f"events/{k}"].tolist() for k in EVENT_INT})
        log = [Event(**{k: ev[k][i] for k in EVENT_TEXT + EVENT_INT}) for i in range(unread)]
    sessions = _session_rows(sess)
    smap = SemanticMap(
        classes=classes, objects=table, up_rotation=data["up_rotation"].astype(np.float64),
        events=log, sessions=sessions, frame_keys=set(_text(data["frames"])),
        created=created, unread_events=None if events is True else n_all,
        event_kinds=events if isinstance(events, tuple) else None,
    )
    real = str(resolve_map_path(path))
    ident = _read_ident.pop(real, None)
    # The file read is the base of this map's first commit in place when it is still the file at
    # the path (no os.replace since it was opened): a new session's first checkpoint then costs
    # what changed too. commit_in_place checks the file is unchanged since; a mismatch rewrites.
    if events is True and patchable and ident is not None and ident == path_ident(real):
        _committed[real, id(smap)] = committed(smap, ident)
    return smap


def _session_rows(sess: dict) -> list[dict]:
    """Session rows (column -> value) from the session columns the file has."""
    n_s = len(next(iter(sess.values()))) if sess else 0
    sessions = []
    for i in range(n_s):
        row = {}
        for key, kind in SESSION_COLUMNS.items():
            if key not in sess:  # a column newer than the file: empty
                row[key] = "" if kind == "s" else 0
                continue
            v = sess[key][i]
            row[key] = (v.decode() if isinstance(v, bytes) else str(v)) if kind == "s" else (
                int(v) if kind == "i" else float(v))
        sessions.append(row)
    return sessions


def load_sessions(path) -> list[dict]:
    """The session rows of the map at ``path``, without its objects or its log: what an ingest
    reads before it opens its recordings, to read each as the map's sessions read it."""
    path = Path(path)
    with _reading(path) as source:
        f = _open_checked(path, source)
        try:
            sg = _member(f, "sessions", h5py.Group, path)
            sess = {k: np.asarray(_member(sg, k, h5py.Dataset, path)[()]) for k in SESSION_COLUMNS if k in sg}
        except (OSError, KeyError, ValueError, TypeError, RuntimeError):  # HDF5 errors in damaged data
            raise _truncated(path) from None
        finally:
            f.close()
    _read_ident.pop(str(resolve_map_path(path)), None)  # no commit builds on this read
    _decode_text(sess, "sessions/", path)
    problem = check_sessions(sess, SESSION_COLUMNS)
    if problem:
        raise _damaged(problem, path)
    return _session_rows(sess)


def _commit_failed(path: Path, exc: OSError, size: int) -> MapWriteError:
    if isinstance(exc, NoSpaceError):
        return no_space(path, exc.need, exc.free)
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        return no_space(path, size, free_bytes(path.parent))
    if exc.errno == errno.EFBIG:
        return MapWriteError(f"the new map ({mb(size)}) is over the file-size limit; the map is unchanged", path)
    if exc.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
        return folder_not_writable(path.parent, exc)
    return MapWriteError(f"cannot commit ({exc.strerror}); the map is unchanged", path)


def save_map(smap: SemanticMap, path, in_place: bool = True) -> None:
    """Commit the map atomically (module docstring): in place when this process made the file's
    last commit (and ``in_place``), else the whole file. Raises MapWriteError, with the old map as
    it was, when the new one cannot be written (a full disk: before the map is touched)."""
    path = resolve_map_path(path)
    smap.require_events()
    try:
        journal.recover(path)  # a dead writer's journal (save_map may be called without the lock)
    except OSError as exc:
        raise _commit_failed(path, exc, 0) from None
    key = (str(path), id(smap))
    rec = _committed.pop(key, None)
    for gone in [k for k, r in _committed.items() if r.smap() is None]:  # maps no longer in memory
        del _committed[gone]
    if in_place and rec is not None and rec.smap() is smap:
        try:
            done = commit_in_place(smap, path, rec)
        except OSError as exc:
            _committed[key] = rec  # rolled back (or left for recovery): rec.ident says which
            raise _commit_failed(path, exc, 0) from None
        if done:
            _committed[key] = committed(smap, rec.ident)
            return
    image = map_image(smap)
    try:
        write_bytes_atomic(path, image)
    except OSError as exc:
        raise _commit_failed(path, exc, len(image)) from None
    _committed[key] = committed(smap, file_ident(os.stat(path)))

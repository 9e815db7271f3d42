"""In-place commits of a file with a rollback journal, as SQLite's (file I/O only, no HDF5).

The map store opens the map through an :class:`Overlay`: a file-like object that reads the bytes
the map holds and keeps every write in memory, so the HDF5 library changes the file without
touching the disk. :func:`commit` then writes those changes in place, safely:

1. the journal ``MAP.h5-journal`` beside the map: the old length and the original bytes of every
   range about to be overwritten, with a sha256 of it all; fsync it and the folder;
2. reserve the growth (``posix_fallocate``), write the ranges in place, truncate to the new length,
   fsync the map;
3. unlink the journal and fsync the folder: the commit point.

A journal whose checksum holds is *hot*: the map may be torn, and :func:`recover` writes the
original bytes back, restores the length, fsyncs and removes it. A journal whose checksum fails
was never complete, so the map was never touched: it is removed. A failure before the journal is
complete leaves the map untouched; one after it rolls back at once.

Readers and the writer exclude each other with ``flock`` on the map file itself: the writer holds
it exclusively from the journal's creation to its removal, ltc readers hold it shared while they
read, so an ltc reader only ever sees a whole commit. A journal seen while holding the lock was
left by a writer that died.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import hashlib
import io
import os
import struct
from pathlib import Path

from ltc_cli.fileio import NoSpaceError, free_bytes, fsync_folder

PAGE = 4096
MAGIC = b"LTCJRNL1"
_HEAD = struct.Struct("<8sQQ")  # magic, old length, number of ranges
_RANGE = struct.Struct("<QQ")  # offset, length (then the bytes)
_SUM = 32  # sha256 of everything before it


def journal_path(path) -> Path:
    return Path(f"{path}-journal")


class Overlay(io.RawIOBase):
    """The file behind ``fd`` (``length`` bytes), read with ``os.pread``, with every write kept
    in memory as pages of PAGE bytes; :meth:`changes` gives what to write back."""

    def __init__(self, fd: int, length: int):
        super().__init__()
        self.fd = fd
        self.length = self.initial = length
        self.base = length  # bytes below this, in no dirty page, are the file's
        self.pages: dict[int, bytearray] = {}
        self.pos = 0

    def readable(self):
        return True

    def writable(self):
        return True

    def seekable(self):
        return True

    def seek(self, offset, whence=io.SEEK_SET):
        self.pos = {io.SEEK_SET: 0, io.SEEK_CUR: self.pos, io.SEEK_END: self.length}[whence] + offset
        return self.pos

    def tell(self):
        return self.pos

    def _clean(self, start: int, n: int) -> bytes:
        """n bytes from ``start`` as the file has them (zeros past ``base``)."""
        got = os.pread(self.fd, max(0, min(n, self.base - start)), start) if start < self.base else b""
        return got + bytes(n - len(got))

    def readinto(self, buf):
        view = memoryview(buf).cast("B")
        n = max(0, min(len(view), self.length - self.pos))
        start = self.pos
        view[:n] = self._clean(start, n)
        for page in range(start // PAGE, -(-(start + n) // PAGE)):
            data = self.pages.get(page)
            if data is not None:
                lo, hi = max(start, page * PAGE), min(start + n, (page + 1) * PAGE)
                view[lo - start:hi - start] = data[lo - page * PAGE:hi - page * PAGE]
        self.pos += n
        return n

    def write(self, data):
        data = memoryview(data).cast("B")
        at, end = self.pos, self.pos + len(data)
        while at < end:
            page, off = divmod(at, PAGE)
            buf = self.pages.get(page)
            if buf is None:
                buf = self.pages[page] = bytearray(self._clean(page * PAGE, PAGE))
            k = min(PAGE - off, end - at)
            buf[off:off + k] = data[at - self.pos:at - self.pos + k]
            at += k
        self.pos = end
        self.length = max(self.length, end)
        return len(data)

    def truncate(self, size=None):
        size = self.pos if size is None else size
        if size < self.length:
            self.base = min(self.base, size)
            for page in [p for p in self.pages if (p + 1) * PAGE > size]:
                if page * PAGE >= size:
                    del self.pages[page]
                else:
                    self.pages[page][size - page * PAGE:] = bytes((page + 1) * PAGE - size)
        self.length = size
        return size

    def flush(self):
        pass

    def changes(self) -> list[tuple[int, bytes]]:
        """The written ranges (offset, bytes), adjacent pages joined, cut at the length."""
        # Bytes cut off by a truncation and not written since read as zeros: write them so.
        for page in range(self.base // PAGE, -(-min(self.initial, self.length) // PAGE)):
            if page not in self.pages:
                self.pages[page] = bytearray(self._clean(page * PAGE, PAGE))
        runs: list[tuple[int, bytearray]] = []
        for page in sorted(self.pages):
            if runs and runs[-1][0] + len(runs[-1][1]) == page * PAGE:
                runs[-1][1].extend(self.pages[page])
            else:
                runs.append((page * PAGE, bytearray(self.pages[page])))
        return [(off, bytes(data[:max(0, self.length - off)])) for off, data in runs if off < self.length]


def _journal_bytes(old_length: int, originals: list[tuple[int, bytes]]) -> bytes:
    parts = [_HEAD.pack(MAGIC, old_length, len(originals))]
    for off, data in originals:
        parts += [_RANGE.pack(off, len(data)), data]
    body = b"".join(parts)
    return body + hashlib.sha256(body).digest()


def read_journal(path) -> tuple[int, list[tuple[int, bytes]]] | None:
    """(old length, original ranges) of a complete journal; None for one never completed."""
    raw = Path(path).read_bytes()
    body, digest = raw[:-_SUM], raw[-_SUM:]
    if len(raw) < _HEAD.size + _SUM or hashlib.sha256(body).digest() != digest:
        return None
    magic, old_length, n = _HEAD.unpack_from(body)
    if magic != MAGIC:
        return None
    at, ranges = _HEAD.size, []
    for _ in range(n):
        off, k = _RANGE.unpack_from(body, at)
        ranges.append((off, body[at + _RANGE.size:at + _RANGE.size + k]))
        at += _RANGE.size + k
    return old_length, ranges


def write_runs(fd: int, runs) -> None:
    """Write each (offset, bytes) at its offset (a function of its own for the crash tests)."""
    for off, data in runs:
        view = memoryview(data)
        while view:
            n = os.pwrite(fd, view, off)
            view, off = view[n:], off + n


def _roll_back(fd: int, old_length: int, originals) -> None:
    write_runs(fd, originals)
    os.ftruncate(fd, old_length)
    os.fsync(fd)


def _write_journal(jpath: Path, data: bytes) -> None:
    fd = os.open(jpath, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_CLOEXEC, 0o644)
    try:
        view = memoryview(data)
        while view:
            view = view[os.write(fd, view):]
        os.fsync(fd)
    finally:
        os.close(fd)
    fsync_folder(jpath.parent)


def _unlink(path: Path) -> None:
    with contextlib.suppress(FileNotFoundError):
        os.unlink(path)
    fsync_folder(path.parent)


def commit(path, fd: int, old_length: int, runs: list[tuple[int, bytes]], new_length: int) -> None:
    """Write ``runs`` into the file ``path`` (open as ``fd``, ``old_length`` bytes) and make it
    ``new_length`` long, atomically (module docstring). Raises NoSpaceError (before the file is
    touched) or OSError; on any error the file is as it was, or (if even the rollback failed) its
    hot journal is left for :func:`recover`."""
    path = Path(path)
    jpath = journal_path(path)
    originals = [(off, os.pread(fd, min(len(data), old_length - off), off)) for off, data in runs if off < old_length]
    if new_length < old_length:  # the cut tail too (the runs end at the new length)
        originals.append((new_length, os.pread(fd, old_length - new_length, new_length)))
    journal = _journal_bytes(old_length, originals)
    growth = max(0, new_length - old_length)
    block = max(os.statvfs(path.parent).f_frsize, 1)
    need = -(-len(journal) // block) * block + block + -(-growth // block) * block
    free = free_bytes(path.parent)
    if need > free:
        raise NoSpaceError(len(journal) + growth, free, path)
    fcntl.flock(fd, fcntl.LOCK_EX)  # readers of a whole commit only (they hold LOCK_SH)
    try:
        try:
            _write_journal(jpath, journal)
        except BaseException as exc:
            with contextlib.suppress(OSError):
                os.unlink(jpath)  # never complete: the map is untouched
            if isinstance(exc, OSError) and exc.errno in (errno.ENOSPC, errno.EDQUOT):
                raise NoSpaceError(len(journal) + growth, free_bytes(path.parent), path) from None
            raise
        try:
            if growth and hasattr(os, "posix_fallocate"):
                _reserve(fd, old_length, growth)
            write_runs(fd, runs)
            if new_length != old_length:
                os.ftruncate(fd, new_length)
            os.fsync(fd)
        except BaseException as exc:
            _roll_back(fd, old_length, originals)
            _unlink(jpath)
            if isinstance(exc, OSError) and exc.errno in (errno.ENOSPC, errno.EDQUOT):
                raise NoSpaceError(len(journal) + growth, free_bytes(path.parent), path) from None
            raise
        _unlink(jpath)  # the commit point
    finally:
        fcntl.flock(fd, fcntl.LOCK_UN)


def _reserve(fd: int, offset: int, size: int) -> None:
    try:
        os.posix_fallocate(fd, offset, size)
    except OSError as exc:
        if exc.errno not in (errno.EOPNOTSUPP, errno.EINVAL, errno.ENOSYS):
            raise  # a full disk: the writes below still report ENOSPC where it cannot reserve


def recover(path) -> bool:
    """Roll back or remove the journal a dead writer left beside ``path``; True if there was
    one. Raises OSError when the map or its folder cannot be written."""
    path = Path(path)
    jpath = journal_path(path)
    if not jpath.exists():
        return False
    try:
        fd = os.open(path, os.O_RDWR | os.O_CLOEXEC)
    except FileNotFoundError:  # the map is gone: nothing to restore, and a new map must not get it
        _unlink(jpath)
        return True
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)  # no live writer is mid-commit now
        if not jpath.exists():
            return False
        hot = read_journal(jpath)
        if hot is not None:
            _roll_back(fd, *hot)
        _unlink(jpath)
    finally:
        os.close(fd)
    return True


def rolled_back_view(fd: int, length: int, jpath) -> Overlay | None:
    """The file behind ``fd`` as its hot journal ``jpath`` restores it, in memory (for a reader
    that may not write the map); None when there is no complete journal."""
    try:
        hot = read_journal(jpath)
    except FileNotFoundError:
        return None
    if hot is None:
        return None
    view = Overlay(fd, length)
    old_length, originals = hot
    for off, data in originals:
        view.seek(off)
        view.write(data)
    view.truncate(old_length)
    view.seek(0)
    return view

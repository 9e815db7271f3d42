"""Atomic file replacement: every file ltc writes appears whole or not at all.

A new version of a file is written beside it under a temporary name (``.NAME.tmp-PID``), fsync-ed,
and ``os.replace``-d over the old one; the folder is fsync-ed after. Any failure removes the
temporary file and leaves the old file as it was. A replaced file keeps its permission bits.
"""

from __future__ import annotations

import contextlib
import errno
import os
from pathlib import Path

TEMP_INFIX = ".tmp-"


class NoSpaceError(OSError):
    """Not enough free space for a new file: raised before anything is written."""

    def __init__(self, need: int, free: int, path):
        super().__init__(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))
        self.need = need
        self.free = free


def temp_path(path) -> Path:
    """The temporary name this process writes a new version of ``path`` under."""
    path = Path(path)
    return path.with_name(f".{path.name}{TEMP_INFIX}{os.getpid()}")


def temp_files_of(path) -> list[tuple[Path, int | None]]:
    """Temporary files beside ``path`` left by writers of it: (file, writer pid or None)."""
    path = Path(path)
    prefix = f".{path.name}{TEMP_INFIX}"
    try:
        names = sorted(n for n in os.listdir(path.parent) if n.startswith(prefix))
    except OSError:
        return []
    out = []
    for name in names:
        tail = name[len(prefix):]
        out.append((path.parent / name, int(tail) if tail.isdigit() else None))
    return out


def pid_alive(pid: int | None) -> bool:
    if pid is None or pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # alive, but another user's
        return True
    return True


def remove_temp_files(path) -> list[Path]:
    """Remove every temporary file of ``path``; only for a writer holding the file's lock (then
    no other process is writing it, and each one is the leftover of a killed writer)."""
    removed = []
    for tmp, _pid in temp_files_of(path):
        try:
            tmp.unlink()
            removed.append(tmp)
        except OSError:
            pass  # not ours to remove (another user's): harmless, each writer uses its own name
    return removed


def stale_temp_files(path) -> list[tuple[Path, int]]:
    """Temporary files of ``path`` whose writer is no longer running: (file, size in bytes)."""
    out = []
    for tmp, pid in temp_files_of(path):
        if not pid_alive(pid):
            try:
                out.append((tmp, tmp.stat().st_size))
            except OSError:
                continue
    return out


def free_bytes(folder) -> int:
    """Bytes an unprivileged writer may still use on the filesystem of ``folder``."""
    st = os.statvfs(folder)
    return st.f_bavail * st.f_frsize


def _existing_mode(path: Path) -> int | None:
    try:
        return os.stat(path).st_mode & 0o7777
    except FileNotFoundError:
        return None


def fsync_folder(folder) -> None:
    # After os.replace the new file is in place; making the rename durable is best effort (some
    # filesystems cannot fsync a folder), and a failure here must not report the commit as lost.
    try:
        dfd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(dfd)
    except OSError:
        pass
    finally:
        os.close(dfd)


def _remove_quietly(path: Path) -> None:
    try:
        path.unlink()
    except OSError:
        pass  # gone already, or nothing better to do: the next writer holding the lock removes it


@contextlib.contextmanager
def atomic_target(path):
    """Yield a temporary path beside ``path``; on success fsync it, ``os.replace`` it over
    ``path`` (with the old file's permission bits) and fsync the folder; on any error remove it
    and leave ``path`` as it was.

    The temporary name carries the process id, so two writers never share one; the caller's
    lock (the map store's) or last-writer-wins (exports) decides who replaces the file.
    """
    path = Path(path)
    tmp = temp_path(path)
    mode = _existing_mode(path)
    try:
        yield tmp
        fd = os.open(tmp, os.O_RDONLY)
        try:
            if mode is not None:
                os.fchmod(fd, mode)
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except BaseException:
        _remove_quietly(tmp)
        raise
    fsync_folder(path.parent)


def write_bytes_atomic(path, data: bytes) -> None:
    """Write ``data`` as the new ``path`` atomically.

    The space is checked and reserved (posix_fallocate) before a byte is written, so a full disk
    shows as a NoSpaceError up front, not as a torn write. Raises OSError; on any error the
    temporary file is gone and ``path`` is as it was.
    """
    path = Path(path)
    need = len(data)
    free = free_bytes(path.parent)
    # A file takes whole blocks, plus one for its inode / extent records on most filesystems.
    block = max(os.statvfs(path.parent).f_frsize, 1)
    if -(-need // block) * block + block > free:
        raise NoSpaceError(need, free, path)
    with atomic_target(path) as tmp:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_CLOEXEC, 0o666)
        try:
            _reserve(fd, need)
            view = memoryview(data)
            while view:
                view = view[os.write(fd, view):]
        finally:
            os.close(fd)


def _reserve(fd: int, size: int) -> None:
    if size <= 0 or not hasattr(os, "posix_fallocate"):
        return
    try:
        os.posix_fallocate(fd, 0, size)
    except OSError as exc:
        if exc.errno in (errno.EOPNOTSUPP, errno.EINVAL, errno.ENOSYS):
            return  # the filesystem cannot reserve: the writes below still report ENOSPC
        raise


def write_text_atomic(path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically. Raises OSError."""
    write_bytes_atomic(path, text.encode("utf-8"))


def write_chunks_atomic(path, chunks) -> None:
    """Write the byte strings ``chunks`` (any iterable, consumed once) as the new ``path``
    atomically, without holding them all: the size is not known up front, so a full disk shows as
    an OSError (ENOSPC) part-way, after which the temporary file is gone and ``path`` as it was."""
    with atomic_target(path) as tmp:
        with open(tmp, "wb") as fh:
            for chunk in chunks:
                fh.write(chunk)

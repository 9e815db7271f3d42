"""The writer's lock on a map, and the checks that a map can be written at all.

Every path to a map (symlinks included) is one map: the lock and the commit use the resolved path,
so two writers on ``link.h5 -> real.h5`` and ``real.h5`` exclude each other.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
from pathlib import Path

from ltc_cli.errors import MapLockedError, MapWriteError
from ltc_cli.fileio import free_bytes, remove_temp_files, stale_temp_files, temp_path
from ltc_cli.map import journal


def resolve_map_path(path) -> Path:
    """The file a map path names, symlinks followed: what is locked and replaced."""
    return Path(os.path.realpath(path))


def mb(n: int) -> str:
    return f"{n / 1e6:.1f} MB" if n >= 1e6 else f"{n / 1e6:.3g} MB"


def no_space(path, need: int, free: int) -> MapWriteError:
    return MapWriteError(f"not enough free space to commit (need {mb(need)}, {mb(free)} free); the map is unchanged",
                         path)


def folder_not_writable(folder, exc: OSError) -> MapWriteError:
    return MapWriteError(f"the map's folder is not writable ({exc.strerror}); ltc writes each commit as a new file "
                         "beside the map", folder)


class MapLock:
    """An exclusive advisory lock (flock on ``MAP.h5.lock`` beside the resolved map) held while a
    process writes a map.

    The kernel drops the lock when the holder dies, even by SIGKILL, so a crash never leaves a map
    locked for ever. Taking the lock also checks, before any frame is mapped, that the map can be
    written at all (file not read-only, folder writable, space for at least one commit), and removes
    the temporary files that killed writers left beside the map (``removed``).
    """

    def __init__(self, path):
        self.given = Path(path)
        self.map_path = resolve_map_path(path)
        self.path = Path(str(self.map_path) + ".lock")
        self.fd = None
        self.removed: list[Path] = []

    def acquire(self) -> "MapLock":
        folder = self.map_path.parent
        if not folder.is_dir():
            raise MapWriteError("the map's folder does not exist", folder)
        lock_existed = self.path.exists()
        try:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        except OSError as exc:
            if exc.errno == errno.EROFS or (not lock_existed and exc.errno in (errno.EACCES, errno.EPERM)):
                raise folder_not_writable(folder, exc) from None
            raise MapLockedError(f"cannot open the lock file ({exc.strerror})", self.path) from None
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
                                     self.given) from None
            raise
        self.fd = fd
        try:
            os.ftruncate(fd, 0)
            os.pwrite(fd, str(os.getpid()).encode(), 0)
            # Holding the lock, no other process writes this map: every temporary file of it is
            # the leftover of a killed writer (a reused pid included), and only takes space.
            self.removed = remove_temp_files(self.map_path)
            with contextlib.suppress(OSError):  # a folder that cannot be written is named just below
                journal.recover(self.map_path)
            check_writable(self.map_path)
        except BaseException:
            self.release()
            raise
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


def orphan_temp_files(path) -> list[tuple[Path, int]]:
    """Temporary files beside map ``path`` whose writer is gone: (file, size in bytes)."""
    return stale_temp_files(resolve_map_path(path))


def check_writable(path) -> None:
    """Raise MapWriteError unless map ``path`` can be committed: the file (when there is one) is
    not read-only, the folder takes a new file, and there is room for a map at least as large."""
    path = resolve_map_path(path)
    try:
        st = os.stat(path)
    except FileNotFoundError:
        st = None
    # os.replace would swap a read-only file out without asking (and root may write anything):
    # the owner's write bits say what the owner wants.
    if st is not None and (not st.st_mode & 0o222 or not os.access(path, os.W_OK)):
        raise MapWriteError(f"the map file is read-only (mode {st.st_mode & 0o777:04o}); make it writable "
                            "(chmod u+w) to ingest into it", path)
    probe = temp_path(path)
    try:
        os.close(os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
        os.unlink(probe)
    except OSError as exc:
        raise folder_not_writable(path.parent, exc) from None
    need = st.st_size if st is not None else 0
    free = free_bytes(path.parent)
    if need > free:
        raise no_space(path, need, free)

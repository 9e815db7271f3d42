"""Atomic file replacement: every file ltc writes appears whole or not at all."""

from __future__ import annotations

import contextlib
import os
from pathlib import Path


@contextlib.contextmanager
def atomic_target(path):
    """Yield a temporary path beside ``path``; on success fsync it, ``os.replace`` it over
    ``path`` and fsync the folder; on any error remove it and leave ``path`` as it was.

    The temporary name carries the process id, so two writers never share one; the caller's
    lock (the map store's) or last-writer-wins (exports) decides who replaces the file.
    """
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        yield tmp
        fd = os.open(tmp, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, path)
        dfd = os.open(path.parent, os.O_RDONLY)
        try:
            os.fsync(dfd)
        finally:
            os.close(dfd)
    finally:
        if tmp.exists():
            tmp.unlink()


def write_text_atomic(path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically. Raises OSError."""
    with atomic_target(path) as tmp:
        tmp.write_text(text, encoding="utf-8")

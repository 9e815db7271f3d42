"""A test plugin (loaded with LTC_PLUGINS) that numbers the points of an ingest where a kill can
fall, and SIGKILLs its own process at one of them: deterministic, reproducible kill points, with no
timing involved.

Points: each frame's detection (between frames), and inside every commit. A whole commit: the
temporary file created, its space reserved, half of it written (a torn file), fsync-ed, just before
and just after ``os.replace``. A commit in place (ltc_cli/map/journal.py): the journal created,
half of it written, after each fsync of the journal and the map (and before the folder's, as in a
whole commit), the growth reserved, half the in-place writes done (the middle one torn), just
before and just after the truncation to the new length, just before and just after the journal's
unlink (the commit point). ``LTC_TEST_EVENTS=FILE`` appends each point's name to FILE as it is
reached; ``LTC_TEST_KILL_AT=N`` kills the process at the N-th point (1-based).
"""

import os
import signal

import ltc_cli.fileio as fileio
import ltc_cli.map.journal as journal
from ltc_plugins.recorded import RecordedDetector

_count = 0
_kill_at = int(os.environ.get("LTC_TEST_KILL_AT", "0"))
_log = os.environ.get("LTC_TEST_EVENTS")


def _point(name: str) -> bool:
    """Record a point; True when the process must die here."""
    global _count
    _count += 1
    if _log:
        with open(_log, "a") as fh:
            fh.write(name + "\n")
    return _count == _kill_at


def _die():
    os.kill(os.getpid(), signal.SIGKILL)


def _around(step: str, call, *args):
    """Kill points just before and just after one call."""
    if _point(f"before {step}"):
        _die()
    call(*args)
    if _point(f"after {step}"):
        _die()


class _OsAtPoints:
    """``os`` as the fileio module sees it, with kill points in the calls a commit makes."""

    CREATED, HALF = "temp file created", "half written"

    def __getattr__(self, name):
        return getattr(os, name)

    def open(self, path, flags, *args):
        if flags & os.O_CREAT and _point(self.CREATED):
            _die()
        return os.open(path, flags, *args)

    def posix_fallocate(self, fd, offset, size):
        if _point("space reserved"):
            _die()
        return os.posix_fallocate(fd, offset, size)

    def write(self, fd, data):
        if _point(self.HALF):
            os.write(fd, bytes(data[: len(data) // 2]))
            _die()
        return os.write(fd, data)

    def fsync(self, fd):
        if _point("fsync"):
            _die()
        return os.fsync(fd)

    def replace(self, src, dst):
        _around("replace", os.replace, src, dst)


class _JournalOsAtPoints(_OsAtPoints):
    """``os`` as the journal module sees it: the in-place commit's steps (it writes only the
    journal with ``os.write``)."""

    CREATED, HALF = "journal created", "journal half written"

    def fsync(self, fd):
        os.fsync(fd)
        if _point("after fsync (journal or map)"):
            _die()

    def posix_fallocate(self, fd, offset, size):
        os.posix_fallocate(fd, offset, size)
        if _point("growth reserved"):
            _die()

    def ftruncate(self, fd, size):
        _around("truncate", os.ftruncate, fd, size)

    def unlink(self, path):
        _around("journal unlink", os.unlink, path)


def _write_runs_at_point(fd, runs):
    if _point("in place, half written"):
        half = len(runs) // 2
        off, data = runs[half]
        _write_runs(fd, runs[:half] + [(off, data[: len(data) // 2])])
        _die()
    _write_runs(fd, runs)


fileio.os = _OsAtPoints()
journal.os = _JournalOsAtPoints()
_write_runs = journal.write_runs
journal.write_runs = _write_runs_at_point
_detect = RecordedDetector.detect


def _detect_at_point(self, frame):
    if _point("detect"):
        _die()
    return _detect(self, frame)


RecordedDetector.detect = _detect_at_point

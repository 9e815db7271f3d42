"""Opening a recording: by the reader the user names, or the first installed reader that
recognises the folder."""

from __future__ import annotations

import json
from pathlib import Path

from ltc_cli import plugins
from ltc_cli.errors import RecordingError
from ltc_cli.recordings.conventions import read_poses_as
from ltc_cli.types import Recording


def open_recording(path, reader: str | None = None, options: dict | None = None) -> Recording:
    """Open a recording with the named reader, or the first installed reader that recognises it.
    The option ``pose_convention`` is every reader's: the convention the poses are written in,
    when it is not ltc's (ltc_cli/recordings/conventions.py)."""
    p = Path(path)
    if not p.exists():
        raise RecordingError("recording does not exist", p)
    options = dict(options or {})
    poses = options.pop("pose_convention", None)
    if reader:
        rec = plugins.get("readers", reader).factory.open(p, options)
        return rec if poses is None else read_poses_as(rec, poses)
    for name, reg in sorted(plugins.registry("readers").items()):
        if reg.factory.sniff(p):
            rec = reg.factory.open(p, options)
            return rec if poses is None else read_poses_as(rec, poses)
    known = ", ".join(sorted(plugins.registry("readers")))
    raise RecordingError(f"no reader recognises this folder (installed readers: {known})", p)


def count_frames(paths, reader: str | None = None, options: dict | None = None, sessions: list = ()) -> int:
    """The number of frames of the recordings at ``paths`` (for a progress bar), each read as the
    map's ``sessions`` read it (:func:`as_ingested`)."""
    return sum(len(open_recording(p, *as_ingested(p, list(sessions), reader, options))) for p in paths)


def as_ingested(path, sessions: list, reader: str | None = None,
                options: dict | None = None) -> tuple[str | None, dict]:
    """(reader, options) to read a recording with as the map's latest session that ingested it read
    it (``sessions``: the map's session rows; a source is matched by its resolved path): that
    session's reader unless ``reader`` names one, and its reader options, each overridden by
    ``options``. A ``reader`` other than the session's takes ``options`` alone (the kept ones were
    another reader's). A recording no session read, or read by a map made before ltc kept the
    options, is read as given."""
    options = dict(options or {})
    where = str(Path(path).resolve())
    for row in reversed(sessions):
        try:
            sources, readers = json.loads(row.get("sources") or "[]"), json.loads(row.get("readers") or "[]")
            kept = json.loads(row.get("reader_options") or "[]")
        except ValueError:
            continue
        if where not in sources:
            continue
        i = sources.index(where)
        kept = kept[i] if isinstance(kept, list) and i < len(kept) and isinstance(kept[i], dict) else {}
        known = readers[i] if i < len(readers) and readers[i] in plugins.registry("readers") else None
        if reader is not None and known is not None and reader != known:
            return reader, options
        return reader or known, {**kept, **options}
    return reader, options


def open_as_ingested(path, sessions: list, reader: str | None = None, options: dict | None = None) -> Recording:
    """The recording at ``path`` opened as :func:`as_ingested` says."""
    return open_recording(path, *as_ingested(path, sessions, reader, options))

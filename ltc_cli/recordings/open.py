"""Opening a recording: by the reader the user names, or the first installed reader that
recognises the folder."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from ltc_cli import plugins
from ltc_cli.errors import ConfigError, RecordingError
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


FRAMES_HELP = "START:STOP[:STEP], positions in the recording's frame order (0 is the first; STOP not included)"


def frame_range(text: str) -> slice:
    """``--frames START:STOP[:STEP]`` as a slice of a recording's frames (Python's slicing: either
    end may be left out, ``::2`` is every other frame). ConfigError for anything else: a position
    is a whole number from 0, a step one from 1."""
    parts = str(text).split(":")
    try:
        if not 2 <= len(parts) <= 3:
            raise ValueError
        values = [None if part.strip() == "" else int(part) for part in parts]
    except ValueError:
        raise ConfigError(f"--frames {text!r}: not {FRAMES_HELP}, e.g. 0:1000, 1000: or ::2") from None
    if any(v is not None and v < 0 for v in values) or (len(values) == 3 and values[2] == 0):
        raise ConfigError(f"--frames {text!r}: positions are 0 or more, a step 1 or more")
    return slice(*values)


def frames_text(frames: slice | None) -> str:
    """A frame range as ``ltc info`` shows it and a session row keeps it ("" for every frame)."""
    if frames is None:
        return ""
    start, stop, step = ("" if v is None else str(v) for v in (frames.start, frames.stop, frames.step))
    return f"{start}:{stop}" + (f":{step}" if step not in ("", "1") else "")


def select_frames(rec: Recording, frames: slice | None) -> Recording:
    """The recording with only the frames of ``frames`` (None: all), each keeping its position
    in the whole recording (``FrameRef.index``) and its key, so that a map's frame keys and events
    are the same whichever range read them. RecordingError when the range holds no frame."""
    if frames is None:
        return rec
    chosen = rec.frames[frames]
    if not chosen:
        raise RecordingError(f"--frames {frames_text(frames)} selects none of its {len(rec.frames)} frames", rec.path)
    return dataclasses.replace(rec, frames=chosen)


def count_frames(paths, reader: str | None = None, options: dict | None = None, sessions: list = (),
                 frames: slice | None = None) -> int:
    """The number of frames of the recordings at ``paths`` (for a progress bar), each read as the
    map's ``sessions`` read it (:func:`as_ingested`), in the range ``frames``."""
    return sum(len(select_frames(open_recording(p, *as_ingested(p, list(sessions), reader, options)), frames).frames)
               for p in paths)


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

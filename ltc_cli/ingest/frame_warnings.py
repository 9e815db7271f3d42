"""What an ingest says of one frame: the warnings a reader or detector left on it, and the file its
detections came from. A part of the session (ingest/session.py), kept in its own file."""

from __future__ import annotations

from pathlib import Path

from ltc_cli.errors import FrameError


def report_warnings(frame, warned: set, strict: bool, warn) -> None:
    """Report the warnings a reader or detector left on a usable frame (a ``once`` key only the
    first time in the recording); with ``strict`` the first one stops the ingest as a FrameError."""
    for w in frame.warnings:
        if w.once is not None:
            if w.once in warned:
                continue
            warned.add(w.once)
        if strict:
            raise FrameError(w.message, w.path)
        warn(str(w))


def detections_source(det, frame) -> str:
    """The file a frame's detections came from, for warnings: a recorded detector's JSON file,
    else the image the detector saw."""
    folder = getattr(det, "folder", None)
    if folder is not None:
        return str(Path(folder) / f"{frame.key}.json")
    return str(frame.rgb_path or frame.key)

"""Which frames of a recording its set-up (up axis, floor) reads: evenly spread, the same set
whichever way the recording is listed, and handed on to the ingest so they are decoded once."""

from __future__ import annotations

from ltc_cli.errors import FrameError
from ltc_cli.types import FrameRef, Recording


def _hand_out_once(frame, load):
    """A FrameRef.load that returns ``frame`` (already loaded) the first time, then loads anew."""
    box = [frame]

    def load_once():
        return box.pop() if box else load()

    return load_once


def sample_positions(n_frames: int, n: int) -> list[int]:
    """n positions in 0..n_frames-1 (all when there are fewer frames; n - 1 when n is odd and there is
    no middle frame), evenly spread from the first to the last, the same set
    whichever way the frames are listed: a position p is taken exactly when n_frames - 1 - p is.

    The up axis and the floor are estimated from these frames; a recording read backwards (or by
    another reader that lists it the other way round) must get the same map frame, or its map and
    the forward pass's disagree by the difference of two estimates (tum-fr1-rpy: 0.96 degrees with
    5 frames taken from the front)."""
    if n_frames <= 0 or n <= 0:
        return []
    if n >= n_frames:
        return list(range(n_frames))
    if n == 1:
        return [(n_frames - 1) // 2]
    half = {i * (n_frames - 1) // (n - 1) for i in range(n // 2)}
    if n % 2 and n_frames % 2:
        half.add((n_frames - 1) // 2)  # the middle frame, when there is one (else n - 1 positions)
    return sorted(half | {n_frames - 1 - p for p in half})


def sample_frames_of(rec: Recording, n: int) -> list:
    """Up to n readable frames spread over the recording (``sample_positions``).

    Each sampled frame's ref in ``rec.frames`` is replaced by one that hands this loaded frame out
    on its next load, so that the ingest (or the rrd export) after the set-up does not decode these
    frames a second time."""
    out = []
    for i in sample_positions(len(rec.frames), n):
        ref = rec.frames[i]
        try:
            frame = ref.load()
        except FrameError:
            continue
        out.append(frame)
        if isinstance(rec.frames, list):
            rec.frames[i] = FrameRef(ref.key, ref.index, _hand_out_once(frame, ref.load), ref.pose)
    return out


def load_kept(rec: Recording, i: int):
    """Frame ``i`` of the recording, loaded now and handed to the next load of it (the ingest's), or
    None when it cannot be read (the ingest then reports it)."""
    ref = rec.frames[i]
    try:
        frame = ref.load()
    except FrameError:
        return None
    if isinstance(rec.frames, list):
        rec.frames[i] = FrameRef(ref.key, ref.index, _hand_out_once(frame, ref.load), ref.pose)
    return frame

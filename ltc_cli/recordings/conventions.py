"""Poses written in another convention than ltc's, read as ltc's: the reader option
``-r pose_convention=NAME`` of every reader (``ltc_cli/geometry/pose_agreement.py`` READINGS names them, and
an ingest's set-up names the one a recording's depth agrees with, when it is not ltc's own)."""

from __future__ import annotations

from dataclasses import replace

from ltc_cli.errors import RecordingError
from ltc_cli.geometry.pose_agreement import READINGS
from ltc_cli.types import FrameRef, Recording


def _converted(load, fn):
    def load_converted():
        frame = load()
        frame.T_world_camera = fn(frame.T_world_camera)
        return frame

    return load_converted


def _converted_pose(pose, fn):
    return None if pose is None else (lambda: fn(pose()))


def read_poses_as(rec: Recording, name) -> Recording:
    """``rec`` with every frame's pose read as the convention ``name`` says the file holds it. Its
    identity changes with it: frames read one way are not the frames read the other way."""
    if name not in READINGS:
        raise RecordingError(f"-r pose_convention={name}: not a pose convention ltc knows (one of: "
                             f"{', '.join(READINGS)})", rec.path)
    fn = READINGS[name][1]
    frames = [FrameRef(ref.key, ref.index, _converted(ref.load, fn), _converted_pose(ref.pose, fn))
              for ref in rec.frames]
    return replace(rec, frames=frames, identity=f"{rec.identity}+poses={name}",
                   meta={**rec.meta, "pose_convention": name})

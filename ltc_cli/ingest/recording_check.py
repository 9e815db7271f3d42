"""What an ingest would take from a recording, without mapping it (``ltc check``): the camera, the
depth range and error, the up axis and floor, and whether the poses fit the depth. Reads a few
frames; writes nothing."""

from __future__ import annotations

import numpy as np

from ltc_cli.geometry.pose_agreement import TOLERANCE
from ltc_cli.ingest.frame_setup import frame_setup_for
from ltc_cli.ingest.keyframes import StillFrames, known_pose
from ltc_cli.ingest.pose_check import pose_message
from ltc_cli.ingest.session_row import camera_record
from ltc_cli.text import plural

#: At least this share of the frames still: the camera is probably fixed in place (a warning).
MOSTLY_STILL = 0.5


def still_frames(rec, frames_settings: dict) -> dict | None:
    """How many of the recording's frames an ingest would leave out as a still camera's
    (ingest/keyframes.py), by the poses the reader knows before reading the images; None when it
    does not know them. ``unknown``: frames whose pose cannot be read (an ingest skips them). The
    count takes every other frame as mapped (a frame with a bad image is not known here)."""
    if not rec.frames or any(getattr(ref, "pose", None) is None for ref in rec.frames):
        return None
    still = StillFrames(frames_settings, 1)
    n_still = n_unknown = 0
    for ref in rec.frames:
        T = known_pose(ref)
        if T is None:
            n_unknown += 1
        elif still.still(0, T):
            n_still += 1
        else:
            still.mapped(0, T)
    return {"still": n_still, "unknown": n_unknown, "move_m": frames_settings["still_move"],
            "turn_deg": frames_settings["still_turn"]}


def still_rule(counted: dict) -> str:
    """The still-frame rule in words, for people."""
    turn = counted["turn_deg"]
    degrees = f"{turn:g} degree{'' if turn == 1 else 's'}"
    return f"the camera moved under {counted['move_m']:g} m and turned under {degrees} since the last frame kept"


def still_warning(rec, counted: dict | None) -> str | None:
    """A warning line when most frames are still: a camera fixed in place maps its first frame only."""
    if counted is None or counted["still"] < MOSTLY_STILL * len(rec.frames):
        return None
    return (f"{counted['still']} of {plural(len(rec.frames), 'frame')} are still ({still_rule(counted)}) and would "
            "not be mapped; for a camera fixed in place, --set frames.still_move=null maps every frame")


def check_recording(rec, warn=None, frames_settings: dict | None = None) -> dict:
    """The recording as an ingest's set-up sees it, as a JSON-ready dict; ``warn`` gets the set-up's
    warning lines (the poses' included), and one when most frames are still by ``frames_settings``
    (the settings' ``frames`` section; None: not counted)."""
    verdicts: list = []
    setup = frame_setup_for(rec, warn=warn, on_poses=verdicts.append)
    counted = None if frames_settings is None else still_frames(rec, frames_settings)
    line = still_warning(rec, counted)
    if line and warn is not None:
        warn(line)
    verdict = verdicts[0]
    up = np.asarray(setup.R_up)[2]  # the recording's direction that the map frame makes +z
    how = "estimated" if isinstance(rec.up, str) else ("z" if rec.up is None else "given")
    return {
        "recording": str(rec.path),
        "reader": rec.format,
        "frames": len(rec.frames),
        "still_frames": counted,
        "camera": camera_record(rec, setup.depth_noise),
        "depth_range": list(rec.depth_range) if rec.depth_range else None,
        "up": {"how": how, "direction": up.round(6).tolist(),
               "tilt_deg": round(float(np.degrees(np.arccos(np.clip(up[2], -1.0, 1.0)))), 3)},
        "floor_z": None if setup.floor_z is None else round(float(setup.floor_z), 4),
        "poses": None if verdict is None else {
            "tolerance_m": TOLERANCE, "agree": {k: round(v, 4) for k, v in verdict.agree.items()},
            "better": verdict.better, "disagree": verdict.disagree, "message": pose_message(rec, verdict)},
    }

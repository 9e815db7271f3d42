"""What an ingest would take from a recording, without mapping it (``ltc check``): the camera, the
depth range and error, the up axis and floor, and whether the poses fit the depth. Reads a few
frames; writes nothing."""

from __future__ import annotations

import numpy as np

from ltc_cli.geometry.pose_agreement import TOLERANCE
from ltc_cli.ingest.frame_setup import frame_setup_for
from ltc_cli.ingest.keyframes import fixed_camera_warning, known_pose, still_census
from ltc_cli.ingest.pose_check import pose_message
from ltc_cli.ingest.session_row import camera_record
from ltc_cli.recordings.open import select_frames


def still_frames(rec, frames_settings: dict) -> dict | None:
    """How many of the recording's frames an ingest would leave out as a still camera's
    (ingest/keyframes.py), by the poses the reader knows before reading the images; None when it
    does not know them. ``unknown``: frames whose pose cannot be read (an ingest skips them). The
    count takes every other frame as mapped (a frame with a bad image is not known here)."""
    if not rec.frames or any(getattr(ref, "pose", None) is None for ref in rec.frames):
        return None
    n_still, n_unknown, reach = still_census((known_pose(ref) for ref in rec.frames), frames_settings)
    return {"still": n_still, "unknown": n_unknown, "move_m": frames_settings["still_move"],
            "turn_deg": frames_settings["still_turn"], "reach_m": round(reach.move, 4),
            "reach_deg": round(reach.turn_deg, 3), "fixed": fixed_camera_warning(
                n_still, len(rec.frames), reach, frames_settings, ahead=True)}


def check_recording(rec, warn=None, frames_settings: dict | None = None, frames: slice | None = None) -> dict:
    """The recording as an ingest's set-up sees it, as a JSON-ready dict; ``warn`` gets the set-up's
    warning lines (the poses' included), and one when most frames are still by ``frames_settings``
    (the settings' ``frames`` section; None: not counted). ``frames``: the range an ingest would
    map (``--frames``); its frames are counted, and the set-up is the whole recording's, as an
    ingest of the range measures it."""
    verdicts: list = []
    part = select_frames(rec, frames)
    setup = frame_setup_for(rec, warn=warn, on_poses=verdicts.append)
    counted = None if frames_settings is None else still_frames(part, frames_settings)
    line = None if counted is None else counted.pop("fixed")
    if line and warn is not None:
        warn(line)
    verdict = verdicts[0]
    up = np.asarray(setup.R_up)[2]  # the recording's direction that the map frame makes +z
    how = "estimated" if isinstance(rec.up, str) else ("z" if rec.up is None else "given")
    return {
        "recording": str(rec.path),
        "reader": rec.format,
        "frames": len(part.frames),
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

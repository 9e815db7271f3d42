"""What an ingest would take from a recording, without mapping it (``ltc check``): the camera, the
depth range and error, the up axis and floor, and whether the poses fit the depth. Reads a few
frames; writes nothing."""

from __future__ import annotations

import numpy as np

from ltc_cli.geometry.pose_agreement import TOLERANCE
from ltc_cli.ingest.frame_setup import frame_setup_for
from ltc_cli.ingest.pose_check import pose_message
from ltc_cli.ingest.session_row import camera_record


def check_recording(rec, warn=None) -> dict:
    """The recording as an ingest's set-up sees it, as a JSON-ready dict; ``warn`` gets the set-up's
    warning lines (the poses' included)."""
    verdicts: list = []
    setup = frame_setup_for(rec, warn=warn, on_poses=verdicts.append)
    verdict = verdicts[0]
    up = np.asarray(setup.R_up)[2]  # the recording's direction that the map frame makes +z
    how = "estimated" if isinstance(rec.up, str) else ("z" if rec.up is None else "given")
    return {
        "recording": str(rec.path),
        "reader": rec.format,
        "frames": len(rec.frames),
        "camera": camera_record(rec, setup.depth_noise),
        "depth_range": list(rec.depth_range) if rec.depth_range else None,
        "up": {"how": how, "direction": up.round(6).tolist(),
               "tilt_deg": round(float(np.degrees(np.arccos(np.clip(up[2], -1.0, 1.0)))), 3)},
        "floor_z": None if setup.floor_z is None else round(float(setup.floor_z), 4),
        "poses": None if verdict is None else {
            "tolerance_m": TOLERANCE, "agree": {k: round(v, 4) for k, v in verdict.agree.items()},
            "better": verdict.better, "disagree": verdict.disagree, "message": pose_message(rec, verdict)},
    }

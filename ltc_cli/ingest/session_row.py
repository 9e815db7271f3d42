"""An ingest's session row in the map: what it read, with which settings and camera, how far it got,
and where a still camera's last mapped pose was (ingest/keyframes.py). A session interrupted over
the same recordings is resumed in its own row."""

from __future__ import annotations

import json
from datetime import datetime, timezone
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ltc_cli import __version__
from ltc_cli.errors import LtcError
from ltc_cli.map.model import SemanticMap
from ltc_cli.map.store import load_sessions
from ltc_cli.recordings.open import frames_text
from ltc_cli.types import Recording

if TYPE_CHECKING:
    from ltc_cli.ingest.session import Plan


def now_iso() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def visit_of(row: dict) -> int:
    return max(1, int(row.get("visit") or 0))  # rows written before --revisit hold 0: a first visit


def camera_record(rec: Recording, depth_noise: float | None = None) -> dict:
    """The camera a recording was read with, for its session row: the image size and pinhole
    parameters, the reader's name for the calibration when it chose one (tum: fr1-fr3, or
    ros when the folder's name tells no sensor), and the depth error measured on its frames."""
    intr = rec.intrinsics
    row = {"width": int(intr.width), "height": int(intr.height),
           **{k: round(float(getattr(intr, k)), 6) for k in ("fx", "fy", "cx", "cy")}}
    named = (rec.meta or {}).get("camera")  # recording.yaml's camera section is no name
    row |= {"camera": named} if isinstance(named, str) and named else {}
    return row | ({"depth_noise": round(float(depth_noise), 5)} if depth_noise is not None else {})


def session_row(smap: SemanticMap, plan: "Plan") -> tuple[int, dict]:
    """The map's row of this ingest's session (appended), or the interrupted one it resumes: (index,
    row)."""
    recordings = [s.recording for s in plan.setups]
    identities = [r.identity for r in recordings]
    last = smap.sessions[-1] if smap.sessions else None
    # An interrupted session over the same recordings is resumed, not started anew, so a resumed
    # ingest ends in exactly the map an uninterrupted one makes. A plain run resumes first visits
    # only (so it never adds frames to a revisit); --revisit resumes whichever visit was cut short.
    # A range of the frames (--frames) is its own session, resumed only by the same range.
    frames = frames_text(plan.frames)
    if (last is not None and last["status"] != "complete" and json.loads(last["recordings"]) == identities
            and (plan.revisit or visit_of(last) == 1) and (last.get("frames") or "") == frames):
        last["status"] = "running"
        last["visit"] = visit_of(last)
        return len(smap.sessions) - 1, last
    visit = 1
    if plan.revisit:
        mine = set(identities)
        visit += max((visit_of(s) for s in smap.sessions if mine & set(json.loads(s["recordings"]))), default=0)
    config = plan.settings
    settings = {k: v for k, v in config.items() if k != "detector"}
    if plan.calibration is not None:
        settings["calibration"] = plan.calibration
    row = {
        "started": now_iso(), "finished": "", "status": "running",
        "sources": json.dumps([str(Path(r.path).resolve()) for r in recordings]),
        "recordings": json.dumps(identities),
        "readers": json.dumps([r.format for r in recordings]),
        "reader_options": json.dumps([s.reader_options or {} for s in plan.setups], sort_keys=True, default=str),
        "detector": json.dumps(config["detector"]), "metric": config["association"]["metric"],
        "policy": config["maintenance"]["policy"], "settings": json.dumps(settings),
        "v_other": float(config["maintenance"]["v_other"]), "ltc_version": __version__,
        "frames_done": 0, "frames_skipped": 0, "frames_still": 0, "still_refs": "[]", "visit": visit, "frames": frames,
        "up_rotation": json.dumps([np.asarray(s.R_up).round(9).tolist() for s in plan.setups]),
        "floor_z": json.dumps([None if s.floor_z is None else round(float(s.floor_z), 6) for s in plan.setups]),
        "cameras": json.dumps([camera_record(s.recording, s.depth_noise) for s in plan.setups]),
    }
    smap.sessions.append(row)
    return len(smap.sessions) - 1, row


def sessions_of(map_path) -> list:
    """The session rows of the map at ``map_path``: none when there is no map yet, or when it cannot
    be read now (the ingest then reports why once it holds the map's lock)."""
    if not Path(map_path).exists():
        return []
    try:
        return load_sessions(map_path)
    except LtcError:
        return []

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
from ltc_cli.ingest.frame_setup import FrameSetup
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
    # Unrounded: a resumed session or a revisit sets the recording up from it (kept_setup), and
    # must map as an uninterrupted run does, to the bit.
    return row | ({"depth_noise": float(depth_noise)} if depth_noise is not None else {})


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
        "coverage": "",
        "up_rotation": json.dumps([np.asarray(s.R_up, dtype=np.float64).tolist() for s in plan.setups]),
        "floor_z": json.dumps([None if s.floor_z is None else float(s.floor_z) for s in plan.setups]),
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


def kept_setup(rec: Recording, reader: str | None, options: dict, sessions: list) -> FrameSetup | None:
    """The set-up (up rotation, floor height, depth error) that the map's latest session to read
    ``rec`` (matched by its resolved path) measured, when it read it as now: with the ``reader``
    and ``options`` that recordings/open.as_ingested chose (a reader other than the session's is
    another reading, as there) and to the same format. None for a recording new to the map, read
    another way now, or read by a map made before ltc kept the set-up. A recording the map has read
    before is set up as it was then, so that its sessions stay in one map frame whatever a later
    ltc estimates from its frames."""
    where = str(Path(rec.path).resolve())
    for row in reversed(sessions):
        try:
            sources = json.loads(row.get("sources") or "[]")
            if where not in sources:
                continue
            i = sources.index(where)
            readers, kept = json.loads(row.get("readers") or "[]"), json.loads(row.get("reader_options") or "[]")
            ups, floors = json.loads(row.get("up_rotation") or "[]"), json.loads(row.get("floor_z") or "[]")
            cameras = json.loads(row.get("cameras") or "[]")
            now = json.loads(json.dumps(options or {}, sort_keys=True, default=str))
            if readers[i] != rec.format or reader not in (None, readers[i]) or kept[i] != now:
                return None
            R_up = np.asarray(ups[i], dtype=np.float64)
            floor_z, noise = floors[i], cameras[i].get("depth_noise")
        except (ValueError, IndexError, TypeError, AttributeError):
            return None  # a row without the set-up (an older map): measure it again
        if R_up.shape != (3, 3) or not np.isfinite(R_up).all():
            return None
        return FrameSetup(R_up, None if floor_z is None else float(floor_z), None if noise is None else float(noise))
    return None


def keep_progress(row: dict, still, cover) -> None:
    """What a resumed run goes on from, into the session's row: the last mapped poses of a still
    camera (ingest/keyframes.StillFrames) and the cells the session saw (map/coverage.Coverage)."""
    row["still_refs"], row["coverage"] = still.text(), cover.text()

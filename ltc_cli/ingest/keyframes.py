"""Frames of a camera that has not moved are not mapped (``frames.still_move``, ``frames.still_turn``).

A robot that stops (at a door, behind a person, at its dock) records the same view for as long as
it stands there. The four stages treat every frame as new evidence: eq. 3 weighs a class vector by
its observations, and stage 3 averages boxes by them, so a few hundred frames of one view outweigh
the rest of the route. On tum-fr1-rpy, the camera stopped for 150 frames at three places gave a
"laptop" where there is none, moved the second monitor's box 0.22 m and lost the white mouse
(docs/decisions.md, issue 9, fifty-fourth round). A frame is mapped only when the camera has
moved or turned enough since the last frame mapped, as keyframe-based mapping systems do; the
frames in between are still, recorded as done, and not detected. Where the reader knows the poses
without reading the images (``FrameRef.pose``), they are not even loaded, and a Dask cluster is
never sent them.

Pure numpy; the session (ingest/session.py) applies the decisions.
"""

from __future__ import annotations

import json

import numpy as np

from ltc_cli.errors import FrameError


def turn_degrees(R_a: np.ndarray, R_b: np.ndarray) -> float:
    """The angle (degrees) of the rotation between two orientations (3, 3): trace(R_a^T R_b) =
    1 + 2 cos(angle)."""
    cos = (np.trace(R_a.T @ R_b) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))


def is_still(T_ref: np.ndarray | None, T: np.ndarray, min_move: float | None, min_turn_deg: float | None) -> bool:
    """Whether a camera pose T (4, 4) is still against the last mapped one T_ref (4, 4): moved under
    ``min_move`` metres and turned under ``min_turn_deg`` degrees. None for either setting, or no
    T_ref yet: never still (every frame is mapped, the paper)."""
    if T_ref is None or min_move is None or min_turn_deg is None:
        return False
    if np.linalg.norm(T[:3, 3] - T_ref[:3, 3]) >= min_move:
        return False
    return turn_degrees(T_ref[:3, :3], T[:3, :3]) < min_turn_deg


class StillFrames:
    """The last mapped pose of each recording of a session, and the decisions against it.

    ``refs``: per recording, the last mapped camera-to-world pose (4, 4), or None. :meth:`text` is
    what the session row keeps of them (``still_refs``), so that an interrupted ingest resumes with
    the same reference and ends in the map an uninterrupted one makes.
    """

    def __init__(self, settings: dict, n_recordings: int, refs: list | None = None):
        self.min_move = settings["still_move"]
        self.min_turn = settings["still_turn"]
        refs = [None if ref is None else np.array(ref, dtype=np.float64) for ref in list(refs or [])[:n_recordings]]
        self.refs = refs + [None] * (n_recordings - len(refs))

    @classmethod
    def resumed(cls, settings: dict, n_recordings: int, text: str) -> "StillFrames":
        """From a session row's ``still_refs`` text. What is not a list of 4x4 finite poses (a row
        written before ltc kept them, or damaged) is no reference: the next frame is mapped."""
        try:
            refs = json.loads(text or "[]")
        except ValueError:
            refs = []
        refs = refs if isinstance(refs, list) else []
        return cls(settings, n_recordings, [ref if _is_pose(ref) else None for ref in refs])

    def still(self, recording: int, T_world_camera: np.ndarray) -> bool:
        return is_still(self.refs[recording], T_world_camera, self.min_move, self.min_turn)

    def mapped(self, recording: int, T_world_camera: np.ndarray) -> None:
        self.refs[recording] = np.array(T_world_camera, dtype=np.float64)

    def text(self) -> str:
        """The references as the session row keeps them (JSON; read back by :meth:`resumed`)."""
        return json.dumps([None if ref is None else ref.tolist() for ref in self.refs])

    def judge_ahead(self, recording: int):
        """keep(T_world_camera) -> bool for a look-ahead that decides, in recording order, which of
        the next frames to detect: a copy of this recording's reference, moved to each frame it keeps.
        It agrees with :meth:`still` as long as every frame kept is mapped; where one is not (its
        detections were bad), the session's own decision stands (ingest/session.py)."""
        ahead = StillFrames({"still_move": self.min_move, "still_turn": self.min_turn}, 1, [self.refs[recording]])

        def keep(T_world_camera: np.ndarray) -> bool:
            if ahead.still(0, T_world_camera):
                return False
            ahead.mapped(0, T_world_camera)
            return True
        return keep


class Reach:
    """How far a recording's camera went from its first pose: the largest distance (m) and turn
    (degrees) of any pose given to :meth:`add` from the first one."""

    def __init__(self):
        self.T_first: np.ndarray | None = None
        self.move = 0.0
        self.turn_deg = 0.0

    def add(self, T_world_camera: np.ndarray) -> None:
        if self.T_first is None:
            self.T_first = np.array(T_world_camera, dtype=np.float64)
            return
        self.move = max(self.move, float(np.linalg.norm(T_world_camera[:3, 3] - self.T_first[:3, 3])))
        self.turn_deg = max(self.turn_deg, turn_degrees(self.T_first[:3, :3], T_world_camera[:3, :3]))


#: A camera taken for one fixed in place (a warning, not a rule): most frames still, and no pose
#: further than FIXED_MOVE metres or FIXED_TURN degrees from the first. A robot that waits at its
#: dock or behind a person and then drives on leaves both bounds, and is not warned.
MOSTLY_STILL, FIXED_MOVE, FIXED_TURN = 0.5, 0.1, 5.0


def still_rule(move_m: float, turn_deg: float) -> str:
    """The still-frame rule in words, for people."""
    degrees = f"{turn_deg:g} degree{'' if turn_deg == 1 else 's'}"
    return f"the camera moved under {move_m:g} m and turned under {degrees} since the last frame kept"


def fixed_camera_warning(n_still: int, n_frames: int, reach: Reach, settings: dict, ahead: bool = False) -> str | None:
    """A warning line when a recording's camera seems fixed in place (see MOSTLY_STILL): its first
    frame is then the only one mapped, and as no object is detected from two distinct views, none
    is confirmed (maintenance.min_detection_views). None otherwise.
    ``ahead``: said of an ingest to come (``ltc check``), not of one done."""
    if n_frames == 0 or n_still < MOSTLY_STILL * n_frames or reach.move >= FIXED_MOVE or reach.turn_deg >= FIXED_TURN:
        return None
    rule = still_rule(settings["still_move"], settings["still_turn"])
    return (f"{n_still} of {n_frames} frames {'are' if ahead else 'were'} still ({rule}) and "
            f"{'would not be' if ahead else 'were not'} mapped: the camera never left {FIXED_MOVE:g} m and "
            f"{FIXED_TURN:g} degrees of its first pose. ltc maps a moving camera's route and confirms an object "
            "only from two distinct views; for a camera fixed in place, see README.md, 'A camera fixed in place'")


def still_census(poses, settings: dict) -> tuple[int, int, Reach]:
    """Over a recording's poses (4, 4) in order, None where unknown: how many frames an ingest leaves
    out as still, how many poses are unknown, and the camera's :class:`Reach`; every frame that is
    not still is taken as mapped (a frame with a bad image is not known before it is read)."""
    still, reach = StillFrames(settings, 1), Reach()
    n_still = n_unknown = 0
    for T in poses:
        if T is None:
            n_unknown += 1
            continue
        reach.add(T)
        if still.still(0, T):
            n_still += 1
        else:
            still.mapped(0, T)
    return n_still, n_unknown, reach


def fixed_camera_after(refs, n_still: int, reach: Reach, n_already: int, resumed: bool, settings: dict) -> str | None:
    """The warning of a camera fixed in place at the end of a recording's ingest (None: none).
    ``n_still`` and ``reach`` are of the frames this run saw, ``n_already`` the recording's frames it
    skipped as already in the map, ``resumed`` whether it goes on with an interrupted session. Frames
    done by earlier runs of the session are judged again from their poses, as ``ltc check`` judges
    them; without every pose known before loading, not at all (a warning from part of the frames
    could be wrong either way). A finished recording run again without ``--revisit`` changes
    nothing and is not warned of again."""
    if n_already:
        if (n_already == len(refs) and not resumed) or any(getattr(ref, "pose", None) is None for ref in refs):
            return None
        n_still, _, reach = still_census((known_pose(ref) for ref in refs), settings)
    return fixed_camera_warning(n_still, len(refs), reach, settings)


def known_pose(ref) -> np.ndarray | None:
    """The pose (4, 4) of a frame not loaded, when its reader knows it (``FrameRef.pose``); None
    when it does not, or cannot read it (the frame's load then says why, at its turn)."""
    pose = getattr(ref, "pose", None)
    if pose is None:
        return None
    try:
        return pose()
    except FrameError:
        return None


def _is_pose(value) -> bool:
    try:
        T = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        return False
    return T.shape == (4, 4) and bool(np.isfinite(T).all())

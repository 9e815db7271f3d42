"""An ingest's check, at its set-up, that a recording's poses fit its depth
(ltc_cli/geometry/pose_agreement.py). Poses in another convention than ltc's make a map of
nonsense without any error; this says which convention they look like before anything is mapped.
"""

from __future__ import annotations

from ltc_cli.geometry.pose_agreement import READINGS, TOLERANCE
from ltc_cli.ingest.sampling import load_kept

#: Pairs of consecutive frames compared: each a frame the set-up read anyway and the one after it.
PAIRS = 4


def frame_pairs(rec, frames: list, n: int = PAIRS) -> list:
    """(depth_a, depth_b, T_world_a, T_world_b, intrinsics) of up to ``n`` of the loaded ``frames``
    (spread over them) and the frame after each in the recording's list (before, for the last)."""
    position = {ref.key: k for k, ref in enumerate(rec.frames)}
    loaded = {position[f.key]: f for f in frames if f.key in position}
    chosen = sorted(loaded)
    m = min(n, len(chosen))
    picks = sorted({round(k * (len(chosen) - 1) / max(m - 1, 1)) for k in range(m)})
    out = []
    for i in (chosen[k] for k in picks):
        j = i + 1 if i + 1 < len(rec.frames) else i - 1
        if j < 0:
            continue
        b = loaded.get(j) or load_kept(rec, j)
        if b is not None:
            loaded[j] = b
            a = loaded[i]
            out.append((a.depth_m, b.depth_m, a.T_world_camera, b.T_world_camera, a.intrinsics))
    return out


def pose_message(rec, verdict) -> str | None:
    """The warning line for ``verdict`` (geometry.pose_agreement.PoseVerdict, or None), else None."""
    if verdict is None:
        return None
    given = verdict.agree["as given"]
    applied = rec.meta.get("pose_convention")
    if verdict.better is not None and applied:
        better = verdict.agree[verdict.better]
        return (f"{rec.path}: read with -r pose_convention={applied}, its poses still do not fit its depth "
                f"(consecutive frames agree on {given:.0%} of depth readings, {better:.0%} with the poses so read "
                f"and then as {READINGS[verdict.better][0]}): try it without -r pose_convention, or with another")
    if verdict.better is not None:
        what, _ = READINGS[verdict.better]
        return (f"{rec.path}: its poses look like {what}: read so, consecutive frames agree "
                f"({verdict.agree[verdict.better]:.0%} of depth readings land within {TOLERANCE * 100:.0f} cm of the "
                f"next frame's, against {given:.0%} as given); the map will be wrong unless they are read so: "
                f"-r pose_convention={verdict.better}")
    if verdict.disagree:
        return (f"{rec.path}: consecutive frames disagree where they overlap (only {given:.0%} of depth readings "
                f"land within {TOLERANCE * 100:.0f} cm of the next frame's): check that the poses are camera-to-world "
                f"with OpenCV camera axes, and the intrinsics and the depth scale")
    return None

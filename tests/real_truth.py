"""What is on the shared real recordings, counted and measured by hand: the truth that
tests/test_real_revisits.py and benchmarks/bench_real.py hold real maps to.

``COUNTS``: per recording, the fewest and most objects of each class (from the recordings'
READMEs; a class not listed must not be in the map).

``TUM_FR1_RPY``: places on tum-fr1-rpy, to say where a map is right and not only whether its
counts are. Each is a pixel on the thing in one frame, back-projected with the median depth of
the 9 x 9 patch around it, the README's intrinsics (fx 517.3, fy 516.5, cx 318.6, cy 255.3) and
the recording's pose (as ltc's TUM reader interpolates it), in the recording's world frame (not
z-up; a map's ``up_rotation`` takes it to the map frame). It lies on the thing's visible surface,
so a box of the thing holds it (within ``NEAR``). ``cls`` None: a place where the map must hold no
box of ``absent`` (a monitor's foot, which YOLOv8n calls "mouse", is part of its monitor).
tests/test_real_revisits.py recomputes every point from the recording.

``APART``: pairs of those places on two different things of one class, which no one box of the
class may hold together (:func:`merged_pairs`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ltc_cli.map.model import ACTIVE, top_class

# tum-fr1-rpy by its README: two flat monitors side by side and a smaller one on the far desk (the
# frames show a fourth behind the front one, docs/decisions.md tenth round), a keyboard, a mouse,
# a mug, a few books, two chairs, and the man at the desk, never mapped. "mouse" up to 3: the white
# mouse by the keyboard, a red corded trackball by the papers (the README's second mouse) and
# a game controller, which COCO has no class for and YOLOv8n calls "mouse" (docs/decisions.md,
# thirtieth round). The monitors' feet it also calls "mouse" are no mice (the landmarks below).
COUNTS = {
    "tum-fr1-rpy": {"tv": (2, 4), "keyboard": (1, 2), "mouse": (1, 3), "cup": (1, 2), "book": (0, 4),
                    "chair": (1, 2), "laptop": (0, 0), "person": (0, 0), "dining table": (0, 2)},
    "dining-room": {"dining table": (1, 1), "chair": (1, 9), "couch": (1, 1), "person": (0, 0)},
}

NEAR = 0.05  # metres: a hand-picked pixel's point lies on the surface, the box around the thing


@dataclass(frozen=True)
class Landmark:
    name: str
    cls: str | None  # the class of the box that must hold it; None: no box of ``absent`` may
    frame: int  # index in the recording's frames (rgb.txt order)
    pixel: tuple[int, int]  # (u, v)
    world_xyz: tuple[float, float, float]
    absent: str | None = None


TUM_FR1_RPY = (
    Landmark("front monitor's screen, middle", "tv", 3, (265, 100), (0.468, 0.898, 1.093)),
    Landmark("second monitor's screen, middle", "tv", 3, (520, 150), (0.539, 1.425, 1.079)),
    Landmark("monitor behind the front one, its back", "tv", 56, (420, 250), (0.079, 0.933, 1.182)),
    Landmark("white mouse right of the keyboard", "mouse", 5, (557, 258), (0.619, 1.232, 0.815)),
    Landmark("red corded trackball by the papers", "mouse", 120, (105, 270), (0.699, 0.229, 0.792)),
    Landmark("game controller by the papers", "mouse", 120, (35, 355), (0.877, 0.164, 0.806)),
    Landmark("white mug", "cup", 120, (355, 175), (0.578, 0.693, 0.878)),
    Landmark("keyboard in front of the monitors, middle", "keyboard", 120, (505, 265), (0.753, 0.937, 0.806)),
    Landmark("book on the desk's left end (Multiple View Geometry)", "book", 42, (130, 170), (0.376, 0.125, 0.809)),
    Landmark("boxes stacked on a book behind it", "book", 42, (140, 85), (0.099, 0.103, 0.855)),
    Landmark("blue office chair behind the desk", "chair", 56, (100, 240), (-1.301, -0.350, 0.855)),
    Landmark("front monitor's foot", None, 3, (250, 215), (0.444, 0.921, 0.795), absent="mouse"),
    Landmark("second monitor's foot", None, 3, (480, 250), (0.563, 1.463, 0.808), absent="mouse"),
)


# Pairs of places on two different things of one class: no box of that class may hold both (one box
# per thing). The trackball and the controller lie 0.19 m apart; YOLOv8n names the trackball in 7
# of the 120 frames that show it and the controller in 8 of 65 (docs/decisions.md, thirty-second
# round). The monitor behind the front one stands right behind it. The two piles the detector calls
# "book" at the desk's left end touch (their boxes 0.36 m apart, centre to centre; docs/decisions.md,
# thirty-eighth round).
APART = {"tum-fr1-rpy": (("front monitor's screen, middle", "second monitor's screen, middle"),
                         ("front monitor's screen, middle", "monitor behind the front one, its back"),
                         ("red corded trackball by the papers", "game controller by the papers"),
                         ("book on the desk's left end (Multiple View Geometry)", "boxes stacked on a book behind it"))}


def box_gaps(point_xyz: np.ndarray, center: np.ndarray, yaw: np.ndarray, size: np.ndarray) -> np.ndarray:
    """(M,) distance from a point (3,) to each Z-oriented box (centres (M, 3), yaws (M,), sizes
    (M, 3)); 0 inside."""
    d = np.asarray(point_xyz, dtype=np.float64)[None, :] - center
    c, s = np.cos(yaw), np.sin(yaw)
    local = np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], d[:, 2]], axis=1)
    return np.linalg.norm(np.maximum(np.abs(local) - size / 2, 0.0), axis=1)


def check(smap, landmarks=TUM_FR1_RPY) -> list[tuple[Landmark, bool, str]]:
    """(landmark, met, what the map has there) for each landmark, over the map's active objects."""
    t = smap.objects
    rows = np.flatnonzero(t.status == ACTIVE)
    names = np.array([smap.classes[int(c)] if c < len(smap.classes) else "other" for c in top_class(t.scores[rows])])
    out = []
    for lm in landmarks:
        point = np.asarray(smap.up_rotation) @ np.asarray(lm.world_xyz)
        cls = lm.cls or lm.absent
        mine = rows[names == cls]
        gaps = box_gaps(point, t.center[mine], t.yaw[mine], t.size[mine])
        near = float(gaps.min()) if gaps.size else np.inf
        oid = int(mine[np.argmin(gaps)]) + 1 if gaps.size else None
        if lm.cls:
            met, where = near <= NEAR, f"nearest {cls} {oid} {near:.2f} m off" if gaps.size else f"no {cls}"
        else:
            met, where = near > NEAR, f"{cls} {oid} on it" if near <= NEAR else f"no {cls} on it"
        out.append((lm, met, where))
    return out


def merged_pairs(smap, pairs, landmarks=TUM_FR1_RPY) -> list[tuple[str, str, int]]:
    """(name, name, object id) for each pair of places (``APART``) that one active box of their
    class holds both of (each within ``NEAR``)."""
    by_name = {lm.name: lm for lm in landmarks}
    t = smap.objects
    rows = np.flatnonzero(t.status == ACTIVE)
    tops = top_class(t.scores[rows])
    out = []
    for a, b in pairs:
        cls = by_name[a].cls
        mine = rows[tops == smap.classes.index(cls)] if cls in smap.classes else rows[:0]
        gap = [box_gaps(np.asarray(smap.up_rotation) @ np.asarray(by_name[n].world_xyz), t.center[mine], t.yaw[mine],
                        t.size[mine]) for n in (a, b)]
        out += [(a, b, int(r) + 1) for r in mine[(gap[0] <= NEAR) & (gap[1] <= NEAR)]]
    return out

"""People walking through: moving boxes of class ``person`` in front of the robot for a few frames
of a lap. They have depth and detections, and are never in the ground truth or the annotations
(a map must not keep them)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ltc_cli.tools.simulate.house import House

PERSON_BASE = 40000  # owner ids of people in the instance image: never a ground-truth id
WALK_LENGTH = 2.0  # metres walked over the frames a person is in view


@dataclass
class Walker:
    """A person: id (>= PERSON_BASE), the frames [first, last] of the walk, start and end (2,) of
    the walk, and the body's boxes in its own frame (x forward, base at z = 0)."""

    id: int
    first: int
    last: int
    start: np.ndarray
    end: np.ndarray
    parts: list  # (offset (3,), size (3,), colour (3,))

    def position(self, frame):
        t = (frame - self.first) / max(1, self.last - self.first)
        return self.start + t * (self.end - self.start)


def body_parts(rng: np.random.Generator) -> list:
    """Legs, torso, arms and head of a person 1.6-1.85 m tall."""
    s = float(rng.uniform(0.95, 1.09))
    shirt = tuple(int(v) for v in rng.uniform(30, 220, 3))
    trousers = tuple(int(v) for v in rng.uniform(20, 120, 3))
    skin = (int(rng.uniform(90, 230)), int(rng.uniform(70, 190)), int(rng.uniform(50, 160)))
    leg, torso, head = 0.82 * s, 0.6 * s, 0.22 * s
    parts = [((0.0, y, leg / 2), (0.14, 0.13, leg), trousers) for y in (-0.09, 0.09)]
    parts.append(((0.0, 0.0, leg + torso / 2), (0.24, 0.4, torso), shirt))
    parts += [((0.0, y, leg + torso - 0.3), (0.1, 0.09, 0.6), shirt) for y in (-0.25, 0.25)]
    parts.append(((0.0, 0.0, leg + torso + 0.03 + head / 2), (0.2, 0.17, head), skin))
    return [(np.array(o, dtype=np.float64), np.array(z, dtype=np.float64), c) for o, z, c in parts]


def plan_walks(house: House, poses: np.ndarray, rng: np.random.Generator, per_room: float) -> list[Walker]:
    """round(per_room * rooms) people (at least one when per_room > 0), each crossing the view of
    the robot (true poses (F, 4, 4)) for 6-12 frames, 1-2.2 m in front of it inside the room's free
    middle, walking across the line of sight."""
    n = 0 if per_room <= 0 else max(1, int(round(per_room * len(house.rooms))))
    F = len(poses)
    out = []
    for k in range(n):
        length = min(F, int(rng.integers(6, 13)))
        first = int(rng.integers(0, F - length + 1))
        mid = poses[first + length // 2]
        forward = mid[:2, 2] / max(1e-9, float(np.hypot(*mid[:2, 2])))
        room = _room_at(house, mid[:2, 3])
        fx0, fy0, fx1, fy1 = room.free
        centre = mid[:2, 3] + forward * 1.0
        for d in np.linspace(2.2, 1.0, 7):  # as far as the free middle allows
            p = mid[:2, 3] + forward * d
            if fx0 + 0.2 <= p[0] <= fx1 - 0.2 and fy0 + 0.2 <= p[1] <= fy1 - 0.2:
                centre = p
                break
        across = np.array([-forward[1], forward[0]]) * (1 if rng.uniform() < 0.5 else -1)
        half = across * WALK_LENGTH / 2
        out.append(Walker(PERSON_BASE + k, first, first + length - 1, centre - half, centre + half, body_parts(rng)))
    return out


def _room_at(house, xy):
    """The room holding xy, else the nearest one (the robot in a doorway)."""
    def dist(r):
        return math.hypot(max(r.x0 - xy[0], 0, xy[0] - r.x1), max(r.y0 - xy[1], 0, xy[1] - r.y1))
    return min(house.rooms, key=dist)


def people_boxes(walkers: list[Walker], frame: int, T_world_camera: np.ndarray) -> list:
    """Boxes (center (3,), yaw, size (3,), colour (3,), owner id) of the people in view at frame; a
    person closer than 0.6 m to the camera has stepped aside (the camera would be inside them)."""
    out = []
    for w in walkers:
        if not w.first <= frame <= w.last:
            continue
        xy = w.position(frame)
        if math.hypot(*(xy - T_world_camera[:2, 3])) < 0.6:
            continue
        d = w.end - w.start
        yaw = math.atan2(d[1], d[0])
        c, s = math.cos(yaw), math.sin(yaw)
        for o, size, color in w.parts:
            out.append((np.array([xy[0] + c * o[0] - s * o[1], xy[1] + s * o[0] + c * o[1], o[2]]), yaw, size,
                        color, w.id))
    return out

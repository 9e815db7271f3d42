"""Recurring false positives: things that are not objects of the vocabulary but that a detector
takes for one from many views (a poster on a wall seen as a tv, clutter on a table seen as a
book). They are drawn like everything else (so depth sees them), kept out of the ground truth and
the annotations, and detected by the realistic detector like objects of their look-alike class.
Unlike the benign profile's one-off blobs, the mapper's two-detection rule does not remove them."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ltc_cli.tools.simulate.house import House
from ltc_cli.tools.simulate.scene import DOOR_WIDTH, WALL_NORMALS, rot2

PHANTOM_BASE = 30000  # owner ids of phantoms in the instance image: never a ground-truth id


@dataclass
class Phantom:
    """A fixed phantom: its id (>= PHANTOM_BASE), look-alike class, pose and boxes (world frame)."""

    id: int
    cls: str
    center: np.ndarray  # (3,)
    yaw: float  # its front (the side a detector sees it from) faces along yaw
    boxes: list  # (center (3,), yaw, size (3,), colour (3,))


def place_phantoms(house: House, rng: np.random.Generator, per_room: float) -> list[Phantom]:
    """round(per_room) phantoms in each room (at least one in the house when per_room > 0),
    alternately a poster on a wall and clutter on a surface (a poster where there is no surface)."""
    out = []
    if per_room <= 0:
        return out
    for room in house.rooms:
        for _ in range(max(1 if not out else 0, int(round(per_room)))):
            surfaces = [i for i, s in enumerate(house.surfaces) if s.room == room.index]
            made = None
            if len(out) % 2 == 1:
                for si in rng.permutation(surfaces).tolist():  # the first with room for it
                    made = made or _clutter(house, rng, si, PHANTOM_BASE + len(out))
            if made is None:
                made = _poster(room, rng, PHANTOM_BASE + len(out))
            if made is not None:
                out.append(made)
    return out


def _poster(room, rng, pid):
    """A thin dark rectangle on a wall (not over a doorway), its middle 1.15-1.35 m high."""
    for _ in range(40):
        side = int(rng.integers(4))
        width, height = float(rng.uniform(0.55, 0.9)), float(rng.uniform(0.45, 0.7))
        lo, hi = (room.x0, room.x1) if side in (0, 2) else (room.y0, room.y1)
        if hi - lo < width + 0.4:
            continue
        along = float(rng.uniform(lo + width / 2 + 0.2, hi - width / 2 - 0.2))
        if any(s == side and abs(a - along) < DOOR_WIDTH / 2 + width / 2 + 0.1 for s, a in room.doors):
            continue
        n = np.array(WALL_NORMALS[side])
        face = {0: (along, room.y0), 2: (along, room.y1), 1: (room.x1, along), 3: (room.x0, along)}[side]
        xy = np.array(face) + n * 0.006
        center = np.array([xy[0], xy[1], float(rng.uniform(1.15, 1.35))])
        yaw = math.atan2(n[1], n[0])
        color = tuple(int(v) for v in rng.uniform(25, 70, 3))
        return Phantom(pid, "tv", center, yaw, [(center, yaw, np.array([0.01, width, height]), color)])
    return None


def _clutter(house, rng, surface_index, pid):
    """A low heap of papers and magazines on a table or cabinet top."""
    size = np.array([float(rng.uniform(0.22, 0.35)), float(rng.uniform(0.18, 0.26)), float(rng.uniform(0.04, 0.08))])
    parts = [(np.array([0.0, 0.0, size[2] / 2]), size, None)]
    spot = house.spot_on_surface(rng, surface_index, parts)
    if spot is None:
        return None
    (x, y), yaw = spot
    z0 = house.surfaces[surface_index].z
    boxes = []
    # Two sheets askew on a pile: a ragged outline, as clutter has.
    for k, (dx, dy, dyaw) in enumerate(((0.0, 0.0, 0.0), (0.06, -0.04, 0.35))):
        off = rot2(yaw) @ np.array([dx, dy])
        s = size if k == 0 else size * np.array([0.8, 0.9, 0.5])
        z = z0 + (s[2] / 2 if k == 0 else size[2] + s[2] / 2)
        boxes.append((np.array([x + off[0], y + off[1], z]), yaw + dyaw, s, tuple(int(v) for v in rng.uniform(170, 235, 3))))
    center = np.array([x, y, z0 + size[2]])
    return Phantom(pid, "book", center, yaw, boxes)

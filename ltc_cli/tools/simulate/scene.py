"""The house's scene model: rooms, objects and the surfaces small things stand on, the room kinds
and what furniture each holds, and the 2D geometry used to place it."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ltc_cli.geometry.boxes import wrap_yaw
from ltc_cli.tools.simulate.furniture import parts_aabb

SCENE_LAYOUT = {
    # rows of room kinds, each row from west to east; the robot visits row 0 west to east, then
    # row 1 east to west (a serpentine, so consecutive rooms share a wall with a doorway).
    "tiny": [["living_dining"]],
    "small": [["living", "kitchen"]],
    "medium": [["living", "kitchen"], ["bathroom", "bedroom"]],
    "large": [["living", "kitchen", "study"], ["bedroom", "bathroom", "bedroom"]],
}

WALL_HEIGHT = 2.5
WALL_THICKNESS = 0.1
DOOR_WIDTH = 0.9
DOOR_HEIGHT = 2.05


@dataclass
class SceneObject:
    """One ground-truth object: parts in its frame, placed at pos (x, y, base z) with yaw."""

    id: int
    cls: str
    room: int
    parts: list
    pos: np.ndarray
    yaw: float
    color: tuple
    movable: bool
    support: int | None = None  # index of the surface it stands on; None = the floor

    def box(self):
        """Ground-truth box: (center (3,), yaw in [-pi/2, pi/2), size (3,)) of all parts."""
        lo, hi = parts_aabb(self.parts)
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        mid = (lo + hi) / 2
        center = np.array(
            [
                self.pos[0] + c * mid[0] - s * mid[1],
                self.pos[1] + s * mid[0] + c * mid[1],
                self.pos[2] + mid[2],
            ]
        )
        # wrap_yaw adds a multiple of pi: the same box with the same sizes.
        return center, float(wrap_yaw(self.yaw)), hi - lo

    def footprint(self, margin=0.0):
        center, yaw, size = self.box()
        return rect(center[:2], yaw, size[:2] + 2 * margin)


@dataclass
class Surface:
    """A horizontal top (table, cabinet) that small objects stand on."""

    center: np.ndarray  # (2,)
    yaw: float
    size: np.ndarray  # (2,)
    z: float
    room: int


@dataclass
class Room:
    index: int
    kind: str
    x0: float
    y0: float
    x1: float
    y1: float  # interior (inner wall faces)
    bands: tuple  # depth of the furniture band along the S, E, N, W walls
    doors: list = field(default_factory=list)  # (side, coordinate along the wall)
    big_side: int = 2  # the wall (0 S, 1 E, 2 N, 3 W) with the deep furniture band
    structure: list = field(default_factory=list)  # footprints (4, 2) of cabinets on the floor

    @property
    def free(self):
        """The middle of the room kept free for the robot: (x0, y0, x1, y1)."""
        s, e, n, w = self.bands
        return (self.x0 + w, self.y0 + s, self.x1 - e, self.y1 - n)

    @property
    def center(self):
        fx0, fy0, fx1, fy1 = self.free
        return np.array([(fx0 + fx1) / 2, (fy0 + fy1) / 2])

    def keepout(self):
        """Polygons (4, 2) no furniture may overlap: the free middle and the way to each door."""
        fx0, fy0, fx1, fy1 = self.free
        polys = [np.array([[fx0, fy0], [fx1, fy0], [fx1, fy1], [fx0, fy1]])]
        for side, along in self.doors:
            depth = self.bands[side] + 0.3
            half = DOOR_WIDTH / 2 + 0.25
            if side == 0:
                a, b = (along - half, self.y0), (along + half, self.y0 + depth)
            elif side == 2:
                a, b = (along - half, self.y1 - depth), (along + half, self.y1)
            elif side == 1:
                a, b = (self.x1 - depth, along - half), (self.x1, along + half)
            else:
                a, b = (self.x0, along - half), (self.x0 + depth, along + half)
            polys.append(np.array([[a[0], a[1]], [b[0], a[1]], [b[0], b[1]], [a[0], b[1]]]))
        return polys

    def door_point(self, side, along, inset):
        """A point ``inset`` metres into the room from the doorway on wall ``side``."""
        if side == 0:
            return np.array([along, self.y0 + inset])
        if side == 2:
            return np.array([along, self.y1 - inset])
        if side == 1:
            return np.array([self.x1 - inset, along])
        return np.array([self.x0 + inset, along])


# Room kinds: nominal interior size (x, y), depth of the furniture band along the walls, and a
# deeper band along one wall without a doorway ("big": for a bed, or a table with chairs on its
# room side); the items placed in it, largest first. An item: (kind, walls, parameters) where walls
# is None (any wall) or "big".
ROOM_KINDS = {
    "living_dining": {
        "size": (5.5, 5.0),
        "band": 1.0,
        "big": 1.05,
        "items": [
            ("dining", "big", {"end_chairs": 2, "side_chairs": 0, "small": ["cup"]}),
            ("couch", None, {}),
            ("tv", None, {"small": []}),
            ("plant", None, {}),
        ],
    },
    "living": {
        "size": (6.0, 5.0),
        "band": 1.0,
        "big": 1.0,
        "items": [
            ("couch", "big", {}),
            ("tv", None, {"small": ["book"]}),
            ("plant", None, {}),
            ("armchair", None, {}),
            ("side_table", None, {"small": ["bottle"]}),
            ("plant", None, {}),
        ],
    },
    "kitchen": {
        "size": (5.0, 5.0),
        "band": 1.0,
        "big": 1.55,
        "items": [
            ("dining", "big", {"end_chairs": 2, "side_chairs": 2, "small": ["cup", "bowl", "bottle"]}),
            ("fridge", None, {}),
            ("oven", None, {}),
            ("sink_counter", None, {}),
        ],
    },
    "bedroom": {
        "size": (5.0, 5.0),
        "band": 1.0,
        "big": 2.25,
        "items": [
            ("bed", "big", {}),
            ("nightstand", "big", {"small": ["book"]}),
            ("tv", None, {"small": ["cup"]}),
            ("plant", None, {}),
            ("armchair", None, {}),
        ],
    },
    "bathroom": {
        "size": (3.5, 3.5),
        "band": 0.8,
        "big": 0.8,
        "items": [
            ("toilet", None, {}),
            ("sink_pedestal", None, {}),
            ("plant_small", None, {}),
        ],
    },
    "study": {
        "size": (4.5, 4.5),
        "band": 1.0,
        "big": 1.4,
        "items": [
            ("desk", "big", {"side_chairs": 1, "small": ["laptop", "book"]}),
            ("couch", None, {}),
            ("bookcase", None, {}),
            ("plant", None, {}),
        ],
    },
}

# Classes that change between laps (furniture people move, things they put down or take away).
MOVABLE = {"chair", "potted plant", "cup", "bowl", "book", "bottle", "laptop"}
SMALL_CLASSES = ("cup", "bowl", "book", "bottle", "laptop")
ADDABLE_FLOOR = ("chair", "potted plant")


def rect(center_xy, yaw, size_xy):
    """Corners (4, 2) counter-clockwise of a rectangle."""
    c, s = math.cos(yaw), math.sin(yaw)
    hx, hy = size_xy[0] / 2, size_xy[1] / 2
    local = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
    return local @ np.array([[c, s], [-s, c]]) + np.asarray(center_xy, dtype=np.float64)


def overlap(pa, pb):
    """True when convex polygons (N, 2), (M, 2) overlap with positive area (separating axes)."""
    for poly in (pa, pb):
        edges = np.roll(poly, -1, axis=0) - poly
        normals = np.stack([-edges[:, 1], edges[:, 0]], axis=1)
        for n in normals:
            a, b = pa @ n, pb @ n
            if a.max() <= b.min() + 1e-9 or b.max() <= a.min() + 1e-9:
                return False
    return True


def inside(poly, x0, y0, x1, y1):
    return bool(
        poly[:, 0].min() >= x0 - 1e-9
        and poly[:, 0].max() <= x1 + 1e-9
        and poly[:, 1].min() >= y0 - 1e-9
        and poly[:, 1].max() <= y1 + 1e-9
    )


WALL_NORMALS = {0: (0.0, 1.0), 1: (-1.0, 0.0), 2: (0.0, -1.0), 3: (1.0, 0.0)}  # inward, per wall


def rot2(yaw):
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s], [s, c]])

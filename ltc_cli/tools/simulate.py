"""A deterministic synthetic house, driven through by a robot, written as ``ltc-recording/1`` folders.

``simulate(outdir, scene, laps, seed)`` builds a house of rooms (walls with doorways, floors) with
furniture of COCO classes, each object made of a few boxes (a chair is a seat, 4 legs and a back of
posts and rails; a table a top and 4 legs) so that masks and depth see the background through the
gaps. A robot follows the same path in every lap: in each room it drives a small loop around the
room's free middle with the camera (1.0 m high, pitched ~12 degrees down) looking outwards at the
furniture along the walls, so every object is seen from several places and often only in part; it
goes from room to room through the doorways. Between laps some objects are moved (same id, new
pose), some removed and some added (new ids).

Per lap folder (``OUTDIR/lap1``, ``OUTDIR/lap2``, ...): recording.yaml, poses.txt (T_world_camera,
OpenCV camera axes, world z up), rgb/<id>.png, depth/<id>.png (uint16, millimetres, 0 = no reading),
annotations/<id>.png (uint16 ground-truth object ids of the visible surface, 0 = none),
detections/<id>.json (a noisy instance-segmentation detector), ground_truth.json (the objects
present in the lap, how much of each was seen, and the changes since the previous lap).

Rendering is exact ray casting against the boxes: for each box, only the pixels of its projected
bounding rectangle are tested (a vectorised slab test in the box's frame), with a z-buffer. The ray
of pixel (u, v) is ((u - cx) / fx, (v - cy) / fy, 1) in the camera frame, so its hit parameter is
the camera-frame depth Z and back-projection by eq. 1 recovers the surface point exactly (up to the
millimetre quantisation of the depth PNG) when the sensor noise is off. The default sensor is
Kinect-like: Gaussian depth noise growing with Z^2, correlated over 8x8-pixel blocks (the sensor
matches windows of about that size), then quantised in disparity; readings outside [0.3, 8] m are
0. RGB is flat-shaded (one brightness per face orientation) with a little block noise, which keeps
the PNGs small.

The detector model (all rates are options, see ``DEFAULTS``): masks come from the true visible
instance image (so occlusion and image borders give partial masks by themselves); objects with too
few visible pixels are not detected; a detection is missed with probability ``miss_rate`` scaled up
for small, far and partly hidden objects; its class is swapped for a similar one (chair <-> couch,
cup <-> bowl, book <-> laptop, ...) with probability ``confusion_rate``; masks are dilated by about
``bleed_px`` pixels onto their neighbours; a mask is sometimes split in two (over-segmentation);
false positives are blobs on walls and floors with a random class. Scores lie in about [0.5, 0.99].
Everything random is drawn from numpy Generators seeded by (seed, lap, frame), so a seed gives
byte-identical files.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml
from PIL import Image
from scipy import ndimage

from ltc_cli.recordings import rle
from ltc_cli.errors import ConfigError, LtcError
from ltc_cli.geometry.boxes import EDGES_BY_AXIS, box_corners, wrap_yaw

# ---------------------------------------------------------------------------------------------
# Vocabulary, colours, options

#: The detector vocabulary written to every recording.yaml (COCO names).
CLASSES = (
    "bed",
    "couch",
    "chair",
    "dining table",
    "tv",
    "refrigerator",
    "oven",
    "sink",
    "toilet",
    "potted plant",
    "cup",
    "bowl",
    "book",
    "bottle",
    "laptop",
)

#: Classes the simulated detector confuses with each other (a real detector's typical mistakes).
CONFUSABLE = {
    "bed": ("couch",),
    "couch": ("chair", "bed"),
    "chair": ("couch",),
    "dining table": ("bed",),
    "tv": ("laptop",),
    "refrigerator": ("oven",),
    "oven": ("refrigerator",),
    "sink": ("toilet",),
    "toilet": ("sink",),
    "potted plant": ("bottle",),
    "cup": ("bowl", "bottle"),
    "bowl": ("cup",),
    "book": ("laptop",),
    "bottle": ("cup",),
    "laptop": ("book", "tv"),
}

_CLASS_COLOR = {
    "bed": (176, 132, 206),
    "couch": (62, 108, 168),
    "chair": (178, 64, 52),
    "dining table": (150, 102, 60),
    "tv": (28, 28, 34),
    "refrigerator": (224, 228, 232),
    "oven": (88, 88, 96),
    "sink": (232, 238, 244),
    "toilet": (244, 244, 238),
    "potted plant": (52, 140, 62),
    "cup": (222, 200, 58),
    "bowl": (238, 138, 58),
    "book": (196, 40, 92),
    "bottle": (58, 170, 150),
    "laptop": (122, 126, 136),
}
_WALL = (214, 208, 196)
_CABINET = (122, 88, 62)
_DARK = (48, 44, 40)
_WOOD = (132, 92, 56)
_SKY = (236, 236, 240)
_FLOOR = {
    "living": (166, 126, 86),
    "living_dining": (166, 126, 86),
    "kitchen": (192, 192, 186),
    "bedroom": (150, 112, 76),
    "bathroom": (202, 212, 216),
    "study": (158, 120, 82),
}

SCENES = ("tiny", "small", "medium", "large")

#: Options of :func:`simulate` and their defaults.
DEFAULTS = {
    # Depth sensor (structured light / stereo, Kinect-like): noise std in metres at 1 m, growing
    # with depth squared; spatially correlated over noise_block x noise_block pixels (the sensor
    # matches ~9x9 pixel windows, so neighbours share their errors; this also keeps the PNGs
    # compressible). Depth is quantised in disparity: the step is depth_resolution at 1 m and grows
    # with depth squared (0: millimetres only).
    "depth_noise": 0.005,
    "depth_resolution": 0.003,
    "noise_block": 8,
    "min_range": 0.3,  # no reading nearer than this (m)
    "max_range": 8.0,  # no reading farther than this (m)
    "rgb_noise": 2.0,  # std of the colour noise in 8-bit levels (also in blocks)
    # Detector.
    "miss_rate": 0.15,
    "confusion_rate": 0.05,
    "bleed_px": 3,
    "false_positive_rate": 0.05,  # per frame
    "split_rate": 0.03,  # a mask split in two (over-segmentation)
    "min_pixels": None,  # fewer visible pixels: never detected; default 5e-4 of the image, >= 20
    # Changes between laps, as fractions of the objects of the previous lap (at least one each
    # when the fraction is above 0).
    "moved_fraction": 0.15,
    "removed_fraction": 0.1,
    "added_fraction": 0.1,
    # Robot path.
    "frames_per_room": None,  # frames of the loop in each room; default per scene
    "transit_step": 0.8,  # metres between frames when going from room to room
    "camera_height": 1.0,
    "camera_pitch_deg": 12.0,
}

_SCENE_LAYOUT = {
    # rows of room kinds, each row from west to east; the robot visits row 0 west to east, then
    # row 1 east to west (a serpentine, so consecutive rooms share a wall with a doorway).
    "tiny": [["living_dining"]],
    "small": [["living", "kitchen"]],
    "medium": [["living", "kitchen"], ["bathroom", "bedroom"]],
    "large": [["living", "kitchen", "study"], ["bedroom", "bathroom", "bedroom"]],
}
_FRAMES_PER_ROOM = {"tiny": 12, "small": 36, "medium": 36, "large": 36}

WALL_HEIGHT = 2.5
WALL_THICKNESS = 0.1
DOOR_WIDTH = 0.9
DOOR_HEIGHT = 2.05
DEPTH_SCALE = 1000.0
PNG_LEVEL = 9  # zlib level: ~10% smaller files than 6 for about twice the encoding time
RECORDING_DEPTH_RANGE = (0.3, 6.0)  # the range written to recording.yaml (reliable readings)


class OutputExistsError(LtcError):
    """A lap folder to write already exists and is not empty."""


# ---------------------------------------------------------------------------------------------
# Scene model

# A part: (offset (3,) in the object frame, size (3,), colour (3,) or None = the object's colour).
# Object frame: x = front (the side facing the room), y = left, z up from the object's base.


@dataclass
class _Obj:
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
        lo, hi = _parts_aabb(self.parts)
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
        return _rect(center[:2], yaw, size[:2] + 2 * margin)


@dataclass
class _Surface:
    """A horizontal top (table, cabinet) that small objects stand on."""

    center: np.ndarray  # (2,)
    yaw: float
    size: np.ndarray  # (2,)
    z: float
    room: int


@dataclass
class _Room:
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
_ROOM_KINDS = {
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
_MOVABLE = {"chair", "potted plant", "cup", "bowl", "book", "bottle", "laptop"}
_SMALL = ("cup", "bowl", "book", "bottle", "laptop")
_ADDABLE_FLOOR = ("chair", "potted plant")


# ---------------------------------------------------------------------------------------------
# Furniture models (parts in the object frame; x = front, y = left, z up from the base)


def _p(offset, size, color=None):
    return (np.array(offset, dtype=np.float64), np.array(size, dtype=np.float64), color)


def _parts_aabb(parts):
    lo = np.min([o - s / 2 for o, s, _ in parts], axis=0)
    hi = np.max([o + s / 2 for o, s, _ in parts], axis=0)
    return lo, hi


def _recenter(parts):
    """Shift parts so that their XY bounding box is centred on the origin and the base is z = 0."""
    lo, hi = _parts_aabb(parts)
    shift = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
    return [(o - shift, s, c) for o, s, c in parts]


def _m_table(rng, length, width, height=0.75):
    top = 0.04
    leg = 0.06
    parts = [_p((0, 0, height - top / 2), (width, length, top))]
    for sx in (-1, 1):
        for sy in (-1, 1):
            parts.append(
                _p(
                    (sx * (width / 2 - leg / 2 - 0.03), sy * (length / 2 - leg / 2 - 0.03), (height - top) / 2),
                    (leg, leg, height - top),
                )
            )
    return parts


def _m_chair(rng):
    w = float(rng.uniform(0.42, 0.5))
    h, leg, st = 0.45, 0.04, 0.05
    parts = [_p((0, 0, h - st / 2), (w, w, st))]
    for sx in (-1, 1):
        for sy in (-1, 1):
            parts.append(_p((sx * (w / 2 - leg / 2), sy * (w / 2 - leg / 2), (h - st) / 2), (leg, leg, h - st)))
    bh = float(rng.uniform(0.4, 0.5))
    bx = -w / 2 + leg / 2
    for sy in (-1, 1):
        parts.append(_p((bx, sy * (w / 2 - leg / 2), h + bh / 2), (leg, leg, bh)))
    parts.append(_p((bx, 0, h + bh - 0.04), (leg, w, 0.08)))  # top rail
    parts.append(_p((bx, 0, h + bh * 0.45), (0.03, w - 2 * leg, 0.05)))  # middle rail
    return parts


def _m_armchair(rng):
    w, d = float(rng.uniform(0.75, 0.9)), float(rng.uniform(0.75, 0.85))
    parts = []
    for sx in (-1, 1):
        for sy in (-1, 1):
            parts.append(_p((sx * (d / 2 - 0.06), sy * (w / 2 - 0.06), 0.06), (0.05, 0.05, 0.12), _DARK))
    parts.append(_p((0, 0, 0.26), (d, w, 0.28)))
    parts.append(_p((-d / 2 + 0.1, 0, 0.6), (0.2, w, 0.4)))
    for sy in (-1, 1):
        parts.append(_p((0.1, sy * (w / 2 - 0.08), 0.5), (d - 0.2, 0.16, 0.2)))
    return parts


def _m_couch(rng):
    L, D = float(rng.uniform(1.7, 2.2)), float(rng.uniform(0.85, 0.95))
    parts = []
    for sx in (-1, 1):
        for sy in (-1, 1):
            parts.append(_p((sx * (D / 2 - 0.06), sy * (L / 2 - 0.06), 0.05), (0.06, 0.06, 0.1), _DARK))
    parts.append(_p((0, 0, 0.25), (D, L, 0.3)))
    parts.append(_p((-D / 2 + 0.11, 0, 0.625), (0.22, L, 0.45)))
    for sy in (-1, 1):
        parts.append(_p((0.11, sy * (L / 2 - 0.09), 0.5), (D - 0.22, 0.18, 0.2)))
    return parts


def _m_bed(rng):
    L, W = float(rng.uniform(1.95, 2.1)), float(rng.uniform(1.4, 1.8))
    parts = []
    for sx in (-1, 1):
        for sy in (-1, 1):
            parts.append(_p((sx * (L / 2 - 0.06), sy * (W / 2 - 0.06), 0.06), (0.08, 0.08, 0.12), _WOOD))
    parts.append(_p((0, 0, 0.245), (L, W, 0.25), _WOOD))
    parts.append(_p((0.015, 0, 0.48), (L - 0.06, W - 0.06, 0.22)))
    parts.append(_p((-L / 2 + 0.03, 0, 0.525), (0.06, W, 1.05), _WOOD))
    parts.append(_p((-L / 2 + 0.26, 0, 0.64), (0.32, W * 0.7, 0.1), (240, 240, 236)))
    return parts


def _m_tv(rng):
    w = float(rng.uniform(0.9, 1.3))
    h = w * 0.58
    return [
        _p((0, 0, 0.12 + h / 2), (0.05, w, h)),
        _p((0, 0, 0.07), (0.04, 0.08, 0.1), _DARK),
        _p((0, 0, 0.01), (0.22, 0.4, 0.02), _DARK),
    ]


def _m_fridge(rng):
    H = float(rng.uniform(1.7, 1.85))
    return [
        _p((0, 0, H / 2), (0.7, 0.75, H)),
        _p((0.35 + 0.035, 0.3, H * 0.62), (0.03, 0.03, 0.6), (150, 150, 155)),
    ]


def _m_oven(rng):
    return [
        _p((0, 0, 0.425), (0.6, 0.6, 0.85)),
        _p((0.3 + 0.035, 0, 0.76), (0.03, 0.45, 0.03), (170, 170, 175)),
        _p((-0.25, 0, 0.91), (0.1, 0.6, 0.12)),
    ]


def _m_basin(z0=0.0):
    return [
        _p((0, 0, z0 + 0.01), (0.42, 0.55, 0.02)),
        _p((0.195, 0, z0 + 0.1), (0.03, 0.55, 0.18)),
        _p((-0.195, 0, z0 + 0.1), (0.03, 0.55, 0.18)),
        _p((0, 0.26, z0 + 0.1), (0.36, 0.03, 0.18)),
        _p((0, -0.26, z0 + 0.1), (0.36, 0.03, 0.18)),
        _p((-0.245, 0, z0 + 0.15), (0.04, 0.04, 0.3), (170, 170, 175)),
        _p((-0.175, 0, z0 + 0.285), (0.14, 0.03, 0.03), (170, 170, 175)),
    ]


def _m_sink_pedestal(rng):
    return _m_basin(0.68) + [_p((0, 0, 0.34), (0.16, 0.16, 0.68))]


def _m_toilet(rng):
    return [
        _p((0.05, 0, 0.125), (0.3, 0.24, 0.25)),
        _p((0.06, 0, 0.325), (0.48, 0.36, 0.15)),
        _p((-0.22, 0, 0.6), (0.18, 0.42, 0.4)),
    ]


def _m_plant(rng, scale=None):
    s = float(rng.uniform(0.8, 1.3)) if scale is None else scale
    return [
        _p((0, 0, 0.14 * s), (0.3 * s, 0.3 * s, 0.28 * s), (168, 84, 44)),
        _p((0, 0, 0.28 * s + 0.125 * s), (0.04, 0.04, 0.25 * s), (40, 90, 40)),
        _p((0, 0, 0.53 * s + 0.225 * s), (0.5 * s, 0.5 * s, 0.45 * s)),
    ]


def _m_small(rng, cls):
    if cls == "cup":
        return [_p((0, 0, 0.05), (0.08, 0.08, 0.1)), _p((0.05, 0, 0.05), (0.02, 0.02, 0.06))]
    if cls == "bowl":
        return [_p((0, 0, 0.035), (0.16, 0.16, 0.07))]
    if cls == "book":
        return [_p((0, 0, 0.0175), (0.17, 0.24, 0.035))]
    if cls == "bottle":
        return [_p((0, 0, 0.1), (0.075, 0.075, 0.2)), _p((0, 0, 0.245), (0.03, 0.03, 0.09))]
    if cls == "laptop":
        return [
            _p((0, 0, 0.01), (0.24, 0.33, 0.02)),
            _p((-0.114, 0, 0.13), (0.012, 0.33, 0.22), (40, 42, 48)),
        ]
    raise ValueError(cls)


# ---------------------------------------------------------------------------------------------
# 2D helpers


def _rect(center_xy, yaw, size_xy):
    """Corners (4, 2) counter-clockwise of a rectangle."""
    c, s = math.cos(yaw), math.sin(yaw)
    hx, hy = size_xy[0] / 2, size_xy[1] / 2
    local = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
    return local @ np.array([[c, s], [-s, c]]) + np.asarray(center_xy, dtype=np.float64)


def _overlap(pa, pb):
    """True when convex polygons (N, 2), (M, 2) overlap with positive area (separating axes)."""
    for poly in (pa, pb):
        edges = np.roll(poly, -1, axis=0) - poly
        normals = np.stack([-edges[:, 1], edges[:, 0]], axis=1)
        for n in normals:
            a, b = pa @ n, pb @ n
            if a.max() <= b.min() + 1e-9 or b.max() <= a.min() + 1e-9:
                return False
    return True


def _inside(poly, x0, y0, x1, y1):
    return bool(
        poly[:, 0].min() >= x0 - 1e-9
        and poly[:, 0].max() <= x1 + 1e-9
        and poly[:, 1].min() >= y0 - 1e-9
        and poly[:, 1].max() <= y1 + 1e-9
    )


_NORMALS = {0: (0.0, 1.0), 1: (-1.0, 0.0), 2: (0.0, -1.0), 3: (1.0, 0.0)}  # inward, per wall


# ---------------------------------------------------------------------------------------------
# House building


class _House:
    """Rooms, walls, structure (cabinets: no class), surfaces and the objects of one lap."""

    def __init__(self, scene: str, rng: np.random.Generator):
        self.scene = scene
        self.rng = rng
        self.rooms: list[_Room] = []
        self.order: list[int] = []  # the robot's room order
        self.door_list: list[tuple] = []  # (room a, side in a, room b, side in b, along)
        self.structure: list[tuple] = []  # (center (3,), yaw, size (3,), colour)
        self.surfaces: list[_Surface] = []
        self.objects: dict[int, _Obj] = {}
        self.next_id = 1
        self._layout()
        self._walls()
        for room in self.rooms:
            self._furnish(room)

    # -- rooms, doors, walls ---------------------------------------------------------------

    def _layout(self):
        rows = _SCENE_LAYOUT[self.scene]
        rng = self.rng
        sizes = [
            [np.array(_ROOM_KINDS[k]["size"]) + rng.uniform(-0.25, 0.25, 2) for k in row] for row in rows
        ]
        total = max(sum(s[0] for s in row) for row in sizes)
        y = 0.0
        grid = []
        for r, row in enumerate(rows):
            depth = max(s[1] for s in sizes[r])
            widths = [s[0] for s in sizes[r]]
            widths[-1] += total - sum(widths)  # every row spans the same width
            x = 0.0
            cells = []
            half = WALL_THICKNESS / 2  # cells are bounded by wall centre lines
            for kind, w in zip(row, widths):
                room = _Room(len(self.rooms), kind, x + half, y + half, x + w - half, y + depth - half, ())
                self.rooms.append(room)
                cells.append(room.index)
                x += w
            grid.append(cells)
            y += depth
        self.width, self.depth = total, y
        order = []
        for r, cells in enumerate(grid):
            order.extend(cells if r % 2 == 0 else cells[::-1])
        self.order = order
        # A doorway between each pair of consecutive rooms of the path.
        for a, b in zip(order[:-1], order[1:]):
            ra, rb = self.rooms[a], self.rooms[b]
            if abs(ra.x1 - rb.x0) < 0.2 or abs(rb.x1 - ra.x0) < 0.2:  # side by side
                lo, hi = max(ra.y0, rb.y0), min(ra.y1, rb.y1)
                along = (lo + hi) / 2 + float(rng.uniform(-0.3, 0.3))
                sa, sb = (1, 3) if ra.x1 < rb.x0 + 0.2 and ra.x0 < rb.x0 else (3, 1)
            else:  # one above the other
                lo, hi = max(ra.x0, rb.x0), min(ra.x1, rb.x1)
                along = (lo + hi) / 2 + float(rng.uniform(-0.3, 0.3))
                sa, sb = (2, 0) if ra.y0 < rb.y0 else (0, 2)
            ra.doors.append((sa, along))
            rb.doors.append((sb, along))
            self.door_list.append((a, sa, b, sb, along))
        # The deep band goes along a wall without a doorway (north first, then south, east, west).
        for room in self.rooms:
            kind = _ROOM_KINDS[room.kind]
            door_sides = {side for side, _ in room.doors}
            room.big_side = next(side for side in (2, 0, 1, 3) if side not in door_sides)
            room.bands = tuple(kind["big"] if side == room.big_side else kind["band"] for side in range(4))

    def _walls(self):
        t, H = WALL_THICKNESS, WALL_HEIGHT
        # Wall lines: (horizontal?, fixed coordinate, start, end), each drawn once.
        lines = {}

        def add(horizontal, fixed, a, b):
            key = (horizontal, round(fixed, 6))
            lines.setdefault(key, []).append((a, b))

        for room in self.rooms:
            fx0, fy0 = room.x0 - t / 2, room.y0 - t / 2
            fx1, fy1 = room.x1 + t / 2, room.y1 + t / 2
            add(True, fy0, fx0, fx1)
            add(True, fy1, fx0, fx1)
            add(False, fx0, fy0, fy1)
            add(False, fx1, fy0, fy1)
        doors = {}
        for a, sa, b, sb, along in self.door_list:
            ra = self.rooms[a]
            fixed = {0: ra.y0 - t / 2, 2: ra.y1 + t / 2, 1: ra.x1 + t / 2, 3: ra.x0 - t / 2}[sa]
            doors.setdefault((sa in (0, 2), round(fixed, 6)), []).append(along)
        for (horizontal, fixed), spans in sorted(lines.items()):
            # Merge the spans of one line (a shared wall appears once per room).
            spans = sorted(spans)
            merged = [list(spans[0])]
            for a, b in spans[1:]:
                if a <= merged[-1][1] + 1e-6:
                    merged[-1][1] = max(merged[-1][1], b)
                else:
                    merged.append([a, b])
            for a, b in merged:
                pieces = [[a - t / 2, b + t / 2]]
                for along in sorted(doors.get((horizontal, fixed), [])):
                    lo, hi = along - DOOR_WIDTH / 2, along + DOOR_WIDTH / 2
                    new = []
                    for p0, p1 in pieces:
                        if hi <= p0 or lo >= p1:
                            new.append([p0, p1])
                            continue
                        if lo > p0:
                            new.append([p0, lo])
                        if hi < p1:
                            new.append([hi, p1])
                        # The lintel over the doorway.
                        self._wall_box(horizontal, fixed, lo, hi, DOOR_HEIGHT, H)
                    pieces = new
                for p0, p1 in pieces:
                    self._wall_box(horizontal, fixed, p0, p1, 0.0, H)
        for room in self.rooms:
            x0, y0 = room.x0 - t / 2, room.y0 - t / 2
            x1, y1 = room.x1 + t / 2, room.y1 + t / 2
            self.structure.append(
                (np.array([(x0 + x1) / 2, (y0 + y1) / 2, -0.05]), 0.0, np.array([x1 - x0, y1 - y0, 0.1]),
                 _FLOOR[room.kind])
            )

    def _wall_box(self, horizontal, fixed, a, b, z0, z1):
        t = WALL_THICKNESS
        if horizontal:
            center, size = ((a + b) / 2, fixed, (z0 + z1) / 2), (b - a, t, z1 - z0)
        else:
            center, size = (fixed, (a + b) / 2, (z0 + z1) / 2), (t, b - a, z1 - z0)
        self.structure.append((np.array(center), 0.0, np.array(size), _WALL))

    # -- furniture ---------------------------------------------------------------------------

    def _floor_blocked(self, room, exclude=None):
        polys = list(room.structure)
        for o in self.objects.values():
            if o.room == room.index and o.support is None and o.id != exclude:
                polys.append(o.footprint())
        return polys

    def _place_on_wall(self, room, depth, width, sides, blocked, tries=80, margin=0.1):
        """A spot (center_xy (2,), yaw) for a footprint depth x width with its back to a wall.

        The footprint's local x (depth) points into the room. None when nothing fits.
        """
        rng = self.rng
        keepout = room.keepout()
        sides = list(range(4)) if sides is None else [room.big_side] if sides == "big" else list(sides)
        for _ in range(tries):
            side = sides[int(rng.integers(len(sides)))]
            n = np.array(_NORMALS[side])
            gap = float(rng.uniform(0.03, 0.08))
            if side in (0, 2):
                lo, hi = room.x0 + width / 2 + 0.02, room.x1 - width / 2 - 0.02
                face = np.array([0.0, room.y0 if side == 0 else room.y1])
                axis = np.array([1.0, 0.0])
            else:
                lo, hi = room.y0 + width / 2 + 0.02, room.y1 - width / 2 - 0.02
                face = np.array([room.x0 if side == 3 else room.x1, 0.0])
                axis = np.array([0.0, 1.0])
            if hi < lo:
                continue
            along = float(rng.uniform(lo, hi))
            center = face * (1 - axis) + axis * along + n * (gap + depth / 2)
            yaw = math.atan2(n[1], n[0])
            poly = _rect(center, yaw, (depth, width))
            if not _inside(poly, room.x0, room.y0, room.x1, room.y1):
                continue
            if any(_overlap(poly, k) for k in keepout):
                continue
            grown = _rect(center, yaw, (depth + 2 * margin, width + 2 * margin))
            if any(_overlap(grown, b) for b in blocked):
                continue
            return center, yaw
        return None

    def _add_object(self, cls, room, parts, pos_xy, base_z, yaw, support=None, color=None):
        base = np.array(_CLASS_COLOR[cls], dtype=np.float64)
        if color is None:
            color = tuple(int(v) for v in np.clip(base * float(self.rng.uniform(0.85, 1.15)), 0, 255))
        obj = _Obj(
            self.next_id, cls, room.index, parts,
            np.array([pos_xy[0], pos_xy[1], base_z], dtype=np.float64), float(yaw), color,
            cls in _MOVABLE, support,
        )
        self.objects[obj.id] = obj
        self.next_id += 1
        return obj

    def _surface_of_parts(self, room, parts, center_xy, yaw, base_z):
        lo, hi = _parts_aabb(parts)
        surf = _Surface(np.array(center_xy, dtype=np.float64), float(yaw), (hi - lo)[:2].copy(),
                        base_z + hi[2], room.index)
        self.surfaces.append(surf)
        return len(self.surfaces) - 1

    def _furnish(self, room):
        for kind, sides, params in _ROOM_KINDS[room.kind]["items"]:
            self._place_item(room, kind, sides, params)

    def _members(self, kind, params):
        """Members of an item in its group frame: (cls | None, parts, (x, y, yaw), base_z, surface)."""
        rng = self.rng
        if kind in ("dining", "desk"):
            if kind == "dining":
                L, W = float(rng.uniform(1.2, 1.5)), float(rng.uniform(0.75, 0.88))
            else:
                L, W = float(rng.uniform(1.0, 1.3)), float(rng.uniform(0.6, 0.7))
            members = [("dining table", _recenter(_m_table(rng, L, W)), (0.0, 0.0, 0.0), 0.0, True)]
            for k in range(params.get("end_chairs", 0)):
                part = _recenter(_m_chair(rng))
                d = _parts_aabb(part)[1][0] - _parts_aabb(part)[0][0]
                sy = 1 if k == 0 else -1
                # A chair at an end of the table, facing it (its front, +x, points at the table).
                members.append(("chair", part, (0.0, sy * (L / 2 + 0.06 + d / 2), -sy * math.pi / 2), 0.0, False))
            n_side = params.get("side_chairs", 0)
            for k in range(n_side):
                part = _recenter(_m_chair(rng))
                d = _parts_aabb(part)[1][0] - _parts_aabb(part)[0][0]
                y = (k + 0.5) / n_side * L - L / 2
                members.append(("chair", part, (W / 2 + 0.06 + d / 2, y, math.pi), 0.0, False))
            return members
        simple = {
            "couch": ("couch", _m_couch),
            "armchair": ("chair", _m_armchair),
            "bed": ("bed", _m_bed),
            "fridge": ("refrigerator", _m_fridge),
            "oven": ("oven", _m_oven),
            "toilet": ("toilet", _m_toilet),
            "sink_pedestal": ("sink", _m_sink_pedestal),
            "plant": ("potted plant", _m_plant),
            "plant_small": ("potted plant", lambda r: _m_plant(r, float(r.uniform(0.6, 0.8)))),
        }
        if kind in simple:
            cls, model = simple[kind]
            return [(cls, _recenter(model(rng)), (0.0, 0.0, 0.0), 0.0, False)]
        if kind == "tv":
            tv = _recenter(_m_tv(rng))
            tv_w = _parts_aabb(tv)[1][1] - _parts_aabb(tv)[0][1]
            # Room beside the tv for a thing or two on the cabinet.
            cab = [_p((0, 0, 0.25), (0.45, tv_w + float(rng.uniform(0.7, 1.0)), 0.5), _CABINET)]
            return [(None, cab, (0.0, 0.0, 0.0), 0.0, True), ("tv", tv, (-0.08, 0.0, 0.0), 0.5, False)]
        if kind == "nightstand":
            return [(None, [_p((0, 0, 0.275), (0.4, 0.45, 0.55), _CABINET)], (0.0, 0.0, 0.0), 0.0, True)]
        if kind == "side_table":
            return [(None, [_p((0, 0, 0.275), (0.5, 0.5, 0.55), _WOOD)], (0.0, 0.0, 0.0), 0.0, True)]
        if kind == "bookcase":
            return [(None, [_p((0, 0, 0.9), (0.35, 0.9, 1.8), _CABINET)], (0.0, 0.0, 0.0), 0.0, False)]
        if kind == "sink_counter":
            cab = [_p((0, 0, 0.36), (0.6, 0.8, 0.72), _CABINET)]
            return [(None, cab, (0.0, 0.0, 0.0), 0.0, False), ("sink", _recenter(_m_basin()), (0.0, 0.0, 0.0), 0.72, False)]
        raise ValueError(kind)

    def _place_item(self, room, kind, sides, params):
        members = self._members(kind, params)
        # Footprint of the group in its frame, then centred.
        polys = []
        for cls, parts, (x, y, yaw), _, _ in members:
            lo, hi = _parts_aabb(parts)
            polys.append(_rect(np.array([x, y]) + _rot2(yaw) @ ((lo + hi)[:2] / 2), yaw, (hi - lo)[:2]))
        pts = np.concatenate(polys)
        gmin, gmax = pts.min(axis=0), pts.max(axis=0)
        gc = (gmin + gmax) / 2
        spot = self._place_on_wall(room, gmax[0] - gmin[0], gmax[1] - gmin[1], sides, self._floor_blocked(room))
        if spot is None:
            return  # no room for it: the house simply has one item less
        center, gyaw = spot
        R = _rot2(gyaw)
        surface_index = None  # the surface of this item (table top, cabinet top) if it has one
        for cls, parts, (x, y, yaw), base_z, surface in members:
            pos = center + R @ (np.array([x, y]) - gc)
            wyaw = gyaw + yaw
            if cls is None:
                # Structure (no class): drawn like walls, blocks the floor, may hold things.
                lo, hi = _parts_aabb(parts)
                for o, s, c in parts:
                    cw = pos + _rot2(wyaw) @ o[:2]
                    self.structure.append((np.array([cw[0], cw[1], base_z + o[2]]), wyaw, s.copy(), c))
                room.structure.append(_rect(pos, wyaw, (hi - lo)[:2]))
                if surface:
                    surface_index = self._surface_of_parts(room, parts, pos, wyaw, base_z)
            else:
                # A member above the floor stands on the item's surface (a tv on its cabinet).
                support = surface_index if (base_z > 0 and surface_index is not None) else None
                self._add_object(cls, room, parts, pos, base_z, wyaw, support=support)
                if surface:
                    surface_index = self._surface_of_parts(room, parts, pos, wyaw, base_z)
        for cls in params.get("small", []):
            if surface_index is not None:
                self._place_small(cls, surface_index)

    def _place_small(self, cls, surface_index, tries=60, exclude=None):
        """Put a new (or, with ``exclude`` = an object, that object) small object on a surface."""
        rng = self.rng
        surf = self.surfaces[surface_index]
        parts = _recenter(_m_small(rng, cls)) if exclude is None else exclude.parts
        lo, hi = _parts_aabb(parts)
        radius = 0.5 * float(np.hypot(*(hi - lo)[:2]))
        half = surf.size / 2 - radius - 0.03
        if np.any(half <= 0):
            return None
        # What already stands on it (a tv on its cabinet, other small things).
        blocked = [o.footprint(0.03) for o in self.objects.values() if o.support == surface_index and o is not exclude]
        R = _rot2(surf.yaw)
        for _ in range(tries):
            local = rng.uniform(-half, half)
            pos = surf.center + R @ local
            yaw = float(rng.uniform(-math.pi, math.pi))
            poly = _rect(pos, yaw, (hi - lo)[:2])
            if any(_overlap(poly, b) for b in blocked):
                continue
            if exclude is not None:
                return pos, yaw
            return self._add_object(cls, self.rooms[surf.room], parts, pos, surf.z, yaw, support=surface_index)
        return None

    # -- changes between laps ----------------------------------------------------------------

    def change(self, rng: np.random.Generator, moved_f, removed_f, added_f):
        """Move, remove and add objects (in place). Returns {"moved", "removed", "added"} ids."""
        self.rng = rng
        ids = sorted(self.objects)
        n = len(ids)

        def count(f):
            return 0 if f <= 0 or n == 0 else max(1, int(round(f * n)))

        movable = [i for i in ids if self.objects[i].movable]
        rng.shuffle(movable)
        moved, removed, added = [], [], []
        for oid in movable:
            if len(moved) >= count(moved_f):
                break
            if self._move(self.objects[oid]):
                moved.append(oid)
        for oid in movable:
            if len(removed) >= count(removed_f):
                break
            if oid not in moved:
                del self.objects[oid]
                removed.append(oid)
        attempts = 0
        while len(added) < count(added_f) and attempts < 20:
            attempts += 1
            if rng.uniform() < 0.5 and self.surfaces:
                cls = _SMALL[int(rng.integers(len(_SMALL)))]
                obj = self._place_small(cls, int(rng.integers(len(self.surfaces))))
            else:
                room = self.rooms[int(rng.integers(len(self.rooms)))]
                cls = _ADDABLE_FLOOR[int(rng.integers(len(_ADDABLE_FLOOR)))]
                parts = _recenter(_m_chair(rng) if cls == "chair" else _m_plant(rng))
                lo, hi = _parts_aabb(parts)
                spot = self._place_on_wall(room, hi[0] - lo[0], hi[1] - lo[1], None, self._floor_blocked(room))
                obj = None if spot is None else self._add_object(cls, room, parts, spot[0], 0.0, spot[1])
            if obj is not None:
                added.append(obj.id)
        return {"moved": sorted(moved), "removed": sorted(removed), "added": sorted(added)}

    def _move(self, obj):
        old = obj.box()[0]
        for _ in range(10):
            if obj.support is not None:
                surface_index = int(self.rng.integers(len(self.surfaces)))
                spot = self._place_small(obj.cls, surface_index, exclude=obj)
            else:
                room = self.rooms[obj.room]
                lo, hi = _parts_aabb(obj.parts)
                spot = self._place_on_wall(room, hi[0] - lo[0], hi[1] - lo[1], None,
                                           self._floor_blocked(room, exclude=obj.id))
                surface_index = None
            if spot is None:
                continue
            pos, yaw = spot
            if np.hypot(*(pos - old[:2])) < 0.3:
                continue
            obj.pos = np.array([pos[0], pos[1], 0.0 if surface_index is None else self.surfaces[surface_index].z])
            obj.yaw = float(yaw)
            if surface_index is not None:
                obj.support = surface_index
                obj.room = self.surfaces[surface_index].room
            return True
        return False

    # -- primitives for rendering ------------------------------------------------------------

    def primitives(self):
        """Arrays of all boxes: center (P, 3), yaw (P,), size (P, 3), colour (P, 3), owner (P,)
        (object id, 0 = walls, floors and cabinets)."""
        centers, yaws, sizes, colors, owners = [], [], [], [], []
        for c, yaw, s, col in self.structure:
            centers.append(c), yaws.append(yaw), sizes.append(s), colors.append(col), owners.append(0)
        for obj in self.objects.values():
            R = _rot2(obj.yaw)
            for o, s, col in obj.parts:
                xy = obj.pos[:2] + R @ o[:2]
                centers.append(np.array([xy[0], xy[1], obj.pos[2] + o[2]]))
                yaws.append(obj.yaw)
                sizes.append(s)
                colors.append(obj.color if col is None else col)
                owners.append(obj.id)
        return (
            np.array(centers, dtype=np.float64),
            np.array(yaws, dtype=np.float64),
            np.array(sizes, dtype=np.float64),
            np.array(colors, dtype=np.float64),
            np.array(owners, dtype=np.int64),
        )


def _rot2(yaw):
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s], [s, c]])


# ---------------------------------------------------------------------------------------------
# Robot path


def _camera_rotation(heading, pitch, roll):
    """R_world_camera (3, 3) for an OpenCV camera looking along ``heading`` (about z), pitched
    down by ``pitch`` and rolled by ``roll`` about its optical axis."""
    cp, sp = math.cos(pitch), math.sin(pitch)
    f = np.array([math.cos(heading) * cp, math.sin(heading) * cp, -sp])  # forward = camera z
    r = np.array([math.sin(heading), -math.cos(heading), 0.0])  # right = camera x
    d = np.cross(f, r)  # down = camera y
    cr, sr = math.cos(roll), math.sin(roll)
    r, d = cr * r + sr * d, -sr * r + cr * d
    return np.stack([r, d, f], axis=1)


def _rot_to_quat(R):
    """Unit quaternion (qx, qy, qz, qw), qw >= 0, of a rotation matrix (3, 3) (Shepperd)."""
    tr = R[0, 0] + R[1, 1] + R[2, 2]
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        q = [(R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s, 0.25 * s]
    elif R[0, 0] > R[1, 1] and R[0, 0] > R[2, 2]:
        s = math.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2]) * 2
        q = [0.25 * s, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s, (R[2, 1] - R[1, 2]) / s]
    elif R[1, 1] > R[2, 2]:
        s = math.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2]) * 2
        q = [(R[0, 1] + R[1, 0]) / s, 0.25 * s, (R[1, 2] + R[2, 1]) / s, (R[0, 2] - R[2, 0]) / s]
    else:
        s = math.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1]) * 2
        q = [(R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, 0.25 * s, (R[1, 0] - R[0, 1]) / s]
    q = np.array(q)
    q /= np.linalg.norm(q)
    return q if q[3] >= 0 else -q


def _path(house: _House, rng, frames_per_room, transit_step, height, pitch_deg):
    """Camera poses T_world_camera (F, 4, 4) of one lap (the same in every lap)."""
    poses = []  # (xy, heading)

    def transit(a, b):
        d = b - a
        dist = float(np.hypot(*d))
        if dist < 1e-6:
            return
        heading = math.atan2(d[1], d[0])
        n = max(1, int(math.ceil(dist / transit_step)))
        for k in range(1, n):
            poses.append((a + d * k / n, heading))

    def loop_point(room, angle):
        # Inset from the free middle's edge, so the camera stays ~0.75 m or more from furniture.
        fx0, fy0, fx1, fy1 = room.free
        rx = max(0.2, (fx1 - fx0) / 2 - 0.75)
        ry = max(0.2, (fy1 - fy0) / 2 - 0.75)
        return room.center + np.array([rx * math.cos(angle), ry * math.sin(angle)])

    order = house.order
    doors = {(a, b): (sa, sb, along) for a, sa, b, sb, along in house.door_list}
    prev_exit = None
    for k, ri in enumerate(order):
        room = house.rooms[ri]
        entry = None
        if k > 0:
            sa, sb, along = doors[(order[k - 1], ri)]
            entry = room.door_point(sb, along, room.bands[sb] + 0.15)
            door_here = room.door_point(sb, along, -WALL_THICKNESS / 2)
            transit(prev_exit, door_here)
            poses.append((door_here, math.atan2(*(entry - door_here)[::-1])))
            transit(door_here, entry)
        if k + 1 < len(order):
            sa, sb, along = doors[(ri, order[k + 1])]
            exit_pt = room.door_point(sa, along, room.bands[sa] + 0.15)
        else:
            exit_pt = None
        target = entry if entry is not None else (exit_pt if exit_pt is not None else room.center + [1.0, 0.0])
        a0 = math.atan2(*(target - room.center)[::-1])
        start = loop_point(room, a0)
        if entry is not None:
            transit(entry, start)
        # The loop: looking outwards (and a little along the way) at the furniture by the walls.
        direction = 1 if (ri % 2 == 0) else -1
        for j in range(frames_per_room):
            ang = a0 + direction * 2 * math.pi * j / frames_per_room
            poses.append((loop_point(room, ang), ang + direction * 0.35))
        if exit_pt is not None:
            transit(start, exit_pt)
            poses.append((exit_pt, math.atan2(*(exit_pt - start)[::-1]) if np.hypot(*(exit_pt - start)) > 1e-6 else a0))
            prev_exit = exit_pt
    out = []
    pitch0 = math.radians(pitch_deg)
    for xy, heading in poses:
        # A little wobble, as a real robot's camera has (the same in every lap).
        pitch = pitch0 + math.radians(float(rng.normal(0, 0.8)))
        roll = math.radians(float(rng.normal(0, 0.5)))
        z = height + float(rng.normal(0, 0.005))
        T = np.eye(4)
        T[:3, :3] = _camera_rotation(heading, pitch, roll)
        T[:3, 3] = [xy[0], xy[1], z]
        out.append(T)
    return np.array(out)


# ---------------------------------------------------------------------------------------------
# Rendering

_ALL_EDGES = np.concatenate(EDGES_BY_AXIS)
_NEAR = 0.05


class _Renderer:
    """Ray casting of boxes with a z-buffer, for one camera."""

    def __init__(self, width, height, fx, fy, cx, cy):
        self.W, self.H = width, height
        self.fx, self.fy, self.cx, self.cy = fx, fy, cx, cy
        u = (np.arange(width, dtype=np.float64) - cx) / fx
        v = (np.arange(height, dtype=np.float64) - cy) / fy
        # Ray of pixel (u, v) in the camera frame, with z = 1: its hit parameter is the depth Z.
        self.rays = np.stack(np.broadcast_arrays(u[None, :], v[:, None], np.ones((height, width))), axis=-1)

    def _rect(self, cam8):
        """Pixel bounds (u0, u1, v0, v1) (half-open, clipped) of a box's corners cam8 (8, 3) and
        its unclipped float bounds, or None when it is behind the camera or off the image."""
        z = cam8[:, 2]
        front = z >= _NEAR
        if not front.any():
            return None
        pts = cam8[front]
        if not front.all():
            a, b = cam8[_ALL_EDGES[:, 0]], cam8[_ALL_EDGES[:, 1]]
            za, zb = a[:, 2] - _NEAR, b[:, 2] - _NEAR
            cross = za * zb < 0
            if cross.any():
                t = za[cross] / (za[cross] - zb[cross])
                pts = np.concatenate([pts, a[cross] + t[:, None] * (b[cross] - a[cross])])
        u = self.fx * pts[:, 0] / pts[:, 2] + self.cx
        v = self.fy * pts[:, 1] / pts[:, 2] + self.cy
        bounds = (u.min(), u.max(), v.min(), v.max())
        u0, u1 = max(0, int(math.floor(bounds[0]))), min(self.W, int(math.ceil(bounds[1])) + 1)
        v0, v1 = max(0, int(math.floor(bounds[2]))), min(self.H, int(math.ceil(bounds[3])) + 1)
        if u0 >= u1 or v0 >= v1:
            return None
        return (u0, u1, v0, v1), bounds

    def render(self, T_wc, centers, yaws, sizes, owners):
        """Depth Z (H, W) (inf = no hit), primitive index (H, W) (-1 = none), face (H, W) (axis * 2
        + (normal along +axis)), and per object id: (unoccluded pixel count, unclipped pixel
        bounds (u0, u1, v0, v1)) for estimating how much of it is hidden or cut by the border."""
        H, W = self.H, self.W
        R_wc, t_wc = T_wc[:3, :3], T_wc[:3, 3]
        zbuf = np.full((H, W), np.inf)
        prim = np.full((H, W), -1, dtype=np.int32)
        face = np.zeros((H, W), dtype=np.int8)
        corners = box_corners(centers, yaws, sizes)  # (P, 8, 3)
        cam = (corners - t_wc) @ R_wc  # R_wc^T (X - t) for every corner
        full = {}
        for p in range(len(centers)):
            r = self._rect(cam[p])
            if r is None:
                continue
            (u0, u1, v0, v1), bounds = r
            c, s = math.cos(yaws[p]), math.sin(yaws[p])
            Rb = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
            M = Rb.T @ R_wc  # camera -> box frame
            o = Rb.T @ (t_wc - centers[p])  # camera centre in the box frame
            d = self.rays[v0:v1, u0:u1] @ M.T  # (h, w, 3) ray directions in the box frame
            d[d == 0] = 1e-30  # a ray parallel to a face: the slab test still works with a huge 1/d
            half = sizes[p] / 2
            t1 = (-half - o) / d
            t2 = (half - o) / d
            tlo = np.minimum(t1, t2)
            thi = np.maximum(t1, t2)
            tnear = tlo.max(axis=2)
            tfar = thi.min(axis=2)
            hit = (tnear <= tfar) & (tnear > _NEAR)
            if not hit.any():
                continue
            oid = int(owners[p])
            if oid:
                cnt, b = full.get(oid, (None, None))
                m = np.zeros((H, W), dtype=bool) if cnt is None else cnt
                m[v0:v1, u0:u1] |= hit
                b = bounds if b is None else (min(b[0], bounds[0]), max(b[1], bounds[1]),
                                              min(b[2], bounds[2]), max(b[3], bounds[3]))
                full[oid] = (m, b)
            zsub = zbuf[v0:v1, u0:u1]
            closer = hit & (tnear < zsub)
            if not closer.any():
                continue
            axis = tlo.argmax(axis=2)
            dax = np.take_along_axis(d, axis[..., None], axis=2)[..., 0]
            fcode = (axis * 2 + (dax < 0)).astype(np.int8)  # the face normal opposes the ray
            zsub[closer] = tnear[closer]
            prim[v0:v1, u0:u1][closer] = p
            face[v0:v1, u0:u1][closer] = fcode[closer]
        stats = {oid: (int(m.sum()), b) for oid, (m, b) in full.items()}
        return zbuf, prim, face, stats


def _shade(prim, face, yaws, colors):
    """Flat shading: each face of a box gets one brightness from its normal and a fixed sun
    (signed, so the four side orientations all differ and box edges stay visible); no gradients
    within a face, which keeps the PNGs small. Returns (H, W, 3) float in [0, 255]."""
    hit = prim >= 0
    p = np.where(hit, prim, 0)
    axis = face // 2
    sign = np.where(face % 2 == 1, 1.0, -1.0)
    local = np.zeros(prim.shape + (3,))
    np.put_along_axis(local, axis[..., None].astype(np.int64), sign[..., None], axis=2)
    c, s = np.cos(yaws[p]), np.sin(yaws[p])
    n = np.stack([c * local[..., 0] - s * local[..., 1], s * local[..., 0] + c * local[..., 1], local[..., 2]], -1)
    sun = np.array([0.35, 0.25, 0.9])
    sun /= np.linalg.norm(sun)
    light = 0.55 + 0.45 * (n @ sun)
    rgb = colors[p] * light[..., None]
    rgb[~hit] = _SKY
    return rgb


def _block_noise(rng, shape, block):
    """Standard normal noise (H, W) constant over block x block pixels."""
    H, W = shape
    b = max(1, int(block))
    small = rng.standard_normal((-(-H // b), -(-W // b)))
    return np.repeat(np.repeat(small, b, axis=0), b, axis=1)[:H, :W]


# ---------------------------------------------------------------------------------------------
# The detector


def _detect(rng, inst, depth_m, stats, classes_of, classes, opts, min_pixels):
    """Instances of one frame from the true visible instance image inst (H, W) (object id, 0 none).

    depth_m (H, W): the depth written (metres, 0 = none); stats: per object id, its unoccluded
    pixel count and unclipped projected bounds (from the renderer); classes_of: object id -> class.
    Returns a list of (class, score, {class: score}, mask (H, W) bool), sorted by score.
    """
    H, W = inst.shape
    out = []
    ids, counts = np.unique(inst[inst > 0], return_counts=True)
    cross = ndimage.generate_binary_structure(2, 1)
    for oid, n in zip(ids.tolist(), counts.tolist()):
        if n < min_pixels:
            continue
        full_n, (bu0, bu1, bv0, bv1) = stats.get(oid, (n, (0, W, 0, H)))
        area = max(1e-9, (bu1 - bu0) * (bv1 - bv0))
        in_img = max(0.0, min(bu1, W) - max(bu0, 0)) * max(0.0, min(bv1, H) - max(bv0, 0))
        visible_frac = min(1.0, n / max(full_n, 1)) * min(1.0, in_img / area)
        mask = inst == oid
        z = depth_m[mask]
        z = z[z > 0]
        dist = float(np.median(z)) if z.size else opts["max_range"]
        far = min(1.0, max(0.0, (dist - 3.0) / 3.0))
        small = min(1.0, max(0.0, 1.0 - n / (10.0 * min_pixels)))
        # The base rate, up to 3x for a mostly hidden or cut object, 2.5x beyond 6 m, 3x near the
        # pixel minimum; miss_rate 0 is a detector that never misses.
        p_miss = opts["miss_rate"] * (1 + 2.0 * (1 - visible_frac) + 1.5 * far + 2.0 * small)
        if rng.uniform() < min(0.97, p_miss):
            continue
        true_cls = classes_of[oid]
        cls = true_cls
        partner = CONFUSABLE.get(true_cls, ())
        if rng.uniform() < opts["confusion_rate"] * (1 + (1 - visible_frac)):
            cls = partner[int(rng.integers(len(partner)))] if partner else classes[int(rng.integers(len(classes)))]
        score = float(rng.uniform(0.62, 0.99)) - 0.2 * (1 - visible_frac) - 0.08 * small
        if cls != true_cls:
            score -= 0.08
        score = float(np.clip(score, 0.5, 0.99))
        second = true_cls if cls != true_cls else (partner[0] if partner else None)
        scores = {cls: score}
        if second is not None and second != cls:
            scores[second] = (1 - score) * float(rng.uniform(0.3, 0.9))
        # Bleed: dilate onto the neighbours (on a crop around the object, for speed).
        k = max(0, int(opts["bleed_px"]) + int(rng.integers(-1, 2))) if opts["bleed_px"] > 0 else 0
        if k:
            vs, us = np.nonzero(mask)
            v0, v1 = max(0, vs.min() - k), min(H, vs.max() + k + 1)
            u0, u1 = max(0, us.min() - k), min(W, us.max() + k + 1)
            grown = ndimage.binary_dilation(mask[v0:v1, u0:u1], structure=cross, iterations=k)
            mask = np.zeros((H, W), dtype=bool)
            mask[v0:v1, u0:u1] = grown
        masks = [mask]
        if n > 4 * min_pixels and rng.uniform() < opts["split_rate"]:
            # Over-segmentation: the mask cut in two across its longer side.
            vs, us = np.nonzero(mask)
            if np.ptp(us) >= np.ptp(vs):
                cut = int(np.median(us))
                a = mask.copy()
                a[:, cut:] = False
            else:
                cut = int(np.median(vs))
                a = mask.copy()
                a[cut:, :] = False
            masks = [a, mask & ~a]
        for m in masks:
            if m.any():
                out.append((cls, score, scores, m))
    if rng.uniform() < opts["false_positive_rate"]:
        # A blob on a wall or the floor, with any class.
        bg = (inst == 0) & (depth_m > 0)
        vs, us = np.nonzero(bg)
        if vs.size:
            j = int(rng.integers(vs.size))
            scale = W / 640.0
            rv, ru = rng.uniform(15, 60, 2) * scale
            vv, uu = np.ogrid[:H, :W]
            blob = (((vv - vs[j]) / rv) ** 2 + ((uu - us[j]) / ru) ** 2 <= 1.0) & bg
            if blob.sum() >= min_pixels:
                cls = classes[int(rng.integers(len(classes)))]
                score = float(rng.uniform(0.5, 0.75))
                out.append((cls, score, {cls: score}, blob))
    out.sort(key=lambda d: -d[1])
    return out


# ---------------------------------------------------------------------------------------------
# Public API


def _options(options):
    unknown = sorted(set(options) - set(DEFAULTS))
    if unknown:
        raise ConfigError(f"unknown simulate option(s): {', '.join(unknown)} (known: {', '.join(DEFAULTS)})")
    opts = dict(DEFAULTS)
    for key, value in options.items():
        if value is None:
            opts[key] = None
            continue
        try:
            v = float(value)
        except (TypeError, ValueError):
            raise ConfigError(f"simulate option {key}: not a number: {value!r}") from None
        if not math.isfinite(v):
            raise ConfigError(f"simulate option {key}: not a finite number: {value!r}")
        opts[key] = v
    for key in ("miss_rate", "confusion_rate", "false_positive_rate", "split_rate",
                "moved_fraction", "removed_fraction", "added_fraction"):
        if not 0.0 <= opts[key] <= 1.0:
            raise ConfigError(f"simulate option {key} must be within [0, 1], not {opts[key]}")
    for key in ("depth_noise", "depth_resolution", "rgb_noise", "bleed_px", "min_range"):
        if opts[key] < 0:
            raise ConfigError(f"simulate option {key} must be >= 0, not {opts[key]}")
    for key in ("noise_block", "transit_step", "camera_height", "max_range"):
        if not opts[key] > 0:
            raise ConfigError(f"simulate option {key} must be > 0, not {opts[key]}")
    if opts["max_range"] <= opts["min_range"]:
        raise ConfigError("simulate option max_range must be above min_range")
    if not -60 <= opts["camera_pitch_deg"] <= 60:
        raise ConfigError("simulate option camera_pitch_deg must be within [-60, 60]")
    if not 0.2 <= opts["camera_height"] <= 2.2:
        raise ConfigError("simulate option camera_height must be within [0.2, 2.2] m (under the ceiling)")
    if opts["frames_per_room"] is not None:
        if opts["frames_per_room"] != int(opts["frames_per_room"]) or not 1 <= opts["frames_per_room"] <= 1000:
            raise ConfigError("simulate option frames_per_room must be an integer in [1, 1000]")
        opts["frames_per_room"] = int(opts["frames_per_room"])
    if opts["min_pixels"] is not None:
        if opts["min_pixels"] < 1:
            raise ConfigError("simulate option min_pixels must be >= 1")
        opts["min_pixels"] = int(opts["min_pixels"])
    opts["bleed_px"] = int(round(opts["bleed_px"]))
    opts["noise_block"] = int(round(opts["noise_block"]))
    return opts


def _check_int(name, value, lo, hi):
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not lo <= value <= hi:
        raise ConfigError(f"simulate: {name} must be an integer in [{lo}, {hi}], not {value!r}")
    return int(value)


def _save_png(path, array):
    # compress_level 9: the images are mostly flat, so this pays (and zlib is deterministic).
    Image.fromarray(array).save(path, format="PNG", compress_level=PNG_LEVEL)


def _box_json(center, yaw, size):
    return [float(v) for v in center], float(yaw), [float(v) for v in size]


def simulate(outdir, scene: str = "small", laps: int = 2, seed: int = 0, width: int = 640,
             height: int = 480, **options) -> dict:
    """Write a synthetic house recording, one ``ltc-recording/1`` folder per lap.

    outdir: the folder to write ``lap1``, ``lap2``, ... into (created as needed); a lap folder that
        exists and is not empty is refused (:class:`OutputExistsError`) before anything is written.
    scene: "tiny" (one room, 7 objects, 12 frames per lap: for tests), "small" (2 rooms),
        "medium" (4 rooms) or "large" (6 rooms).
    laps: how many laps (1-100); lap 1 is the original house, each later lap changes the previous.
    seed: any integer >= 0; the same arguments give byte-identical files.
    width, height: image size; the intrinsics are those of a Kinect-like camera (fx = fy = 525 at
        640 px wide, scaled with the width; principal point in the middle).
    options: see ``DEFAULTS`` (detector noise rates, depth noise, lap changes, path density).

    Returns a summary: {"outdir", "scene", "seed", "width", "height", "classes", "frames_per_lap",
    "objects_per_lap", "changes" (per lap), "laps": [{"lap", "path", "frames", "objects",
    "changes"}], "bytes"}. Raises :class:`ltc_cli.errors.ConfigError` on bad arguments.
    """
    if scene not in SCENES:
        raise ConfigError(f"simulate: unknown scene {scene!r} (choose from {', '.join(SCENES)})")
    laps = _check_int("laps", laps, 1, 100)
    seed = _check_int("seed", seed, 0, 2**63 - 1)
    width = _check_int("width", width, 16, 4096)
    height = _check_int("height", height, 16, 4096)
    opts = _options(options)
    frames_per_room = opts["frames_per_room"] or _FRAMES_PER_ROOM[scene]
    min_pixels = opts["min_pixels"] if opts["min_pixels"] is not None else max(20, int(round(5e-4 * width * height)))

    outdir = Path(outdir)
    lap_dirs = [outdir / f"lap{k}" for k in range(1, laps + 1)]
    for d in lap_dirs:
        if d.exists() and (not d.is_dir() or any(d.iterdir())):
            raise OutputExistsError("exists and is not empty; refusing to overwrite it", path=d)

    fx = fy = 525.0 * width / 640.0
    cx, cy = (width - 1) / 2.0, (height - 1) / 2.0
    renderer = _Renderer(width, height, fx, fy, cx, cy)

    house = _House(scene, np.random.default_rng([seed, 0x5CE7E]))
    poses = _path(house, np.random.default_rng([seed, 0x9A7]), frames_per_room, opts["transit_step"],
                  opts["camera_height"], opts["camera_pitch_deg"])
    classes = list(CLASSES)
    sim_options = dict(opts)
    sim_options["frames_per_room"] = frames_per_room
    sim_options["min_pixels"] = min_pixels

    summary = {
        "outdir": str(outdir), "scene": scene, "seed": seed, "width": width, "height": height,
        "classes": classes, "frames_per_lap": len(poses), "objects_per_lap": [], "changes": [],
        "laps": [], "bytes": 0,
    }
    for lap, lap_dir in enumerate(lap_dirs, start=1):
        if lap == 1:
            changes = {"moved": [], "removed": [], "added": []}
        else:
            changes = house.change(np.random.default_rng([seed, lap, 0xC4A9E]), opts["moved_fraction"],
                                   opts["removed_fraction"], opts["added_fraction"])
        try:
            info = _write_lap(lap_dir, house, poses, renderer, opts, min_pixels, classes, seed, lap, laps,
                              scene, sim_options, changes)
        except OSError as exc:
            raise LtcError(f"cannot write: {exc.strerror or exc}", path=exc.filename or lap_dir) from exc
        summary["objects_per_lap"].append(len(house.objects))
        summary["changes"].append(changes)
        summary["laps"].append({"lap": lap, "path": str(lap_dir), "frames": len(poses),
                                "objects": len(house.objects), "changes": changes})
        summary["bytes"] += info["bytes"]
    return summary


def _write_lap(lap_dir, house, poses, renderer, opts, min_pixels, classes, seed, lap, laps, scene,
               sim_options, changes):
    for sub in ("rgb", "depth", "detections", "annotations"):
        (lap_dir / sub).mkdir(parents=True, exist_ok=True)
    W, H = renderer.W, renderer.H
    meta = {
        "format": "ltc-recording/1",
        "name": f"ltc simulate: {scene} house, seed {seed}, lap {lap} of {laps}",
        "camera": {"width": W, "height": H, "fx": float(renderer.fx), "fy": float(renderer.fy),
                   "cx": float(renderer.cx), "cy": float(renderer.cy)},
        "depth": {"scale": DEPTH_SCALE, "min": RECORDING_DEPTH_RANGE[0], "max": RECORDING_DEPTH_RANGE[1]},
        "up": [0.0, 0.0, 1.0],
        "classes": list(classes),
        "simulator": {"scene": scene, "seed": seed, "lap": lap, "laps": laps, "options": sim_options},
    }
    with open(lap_dir / "recording.yaml", "w", encoding="utf-8") as f:
        yaml.safe_dump(meta, f, sort_keys=False, default_flow_style=None)

    centers, yaws, sizes, colors, owners = house.primitives()
    classes_of = {oid: o.cls for oid, o in house.objects.items()}
    seen_pixels = {oid: 0 for oid in house.objects}
    seen_frames = {oid: 0 for oid in house.objects}
    pose_lines = []
    for i, T in enumerate(poses):
        fid = f"{i:06d}"
        q = _rot_to_quat(T[:3, :3])
        pose_lines.append(" ".join([fid] + [repr(float(v)) for v in (*T[:3, 3], *q)]))
        rng_det, rng_depth, rng_rgb = (np.random.default_rng(s) for s in
                                       np.random.SeedSequence([seed, lap, 0xF4A3E, i]).spawn(3))
        zbuf, prim, face, stats = renderer.render(T, centers, yaws, sizes, owners)
        hit = prim >= 0
        inst = np.where(hit, owners[np.where(hit, prim, 0)], 0).astype(np.uint16)
        # Depth: the true Z plus noise growing with Z^2, in millimetres; 0 = no reading.
        z = np.where(hit, zbuf, 0.0)
        if opts["depth_noise"] > 0:
            z = z + opts["depth_noise"] * z * z * _block_noise(rng_depth, z.shape, opts["noise_block"])
        if opts["depth_resolution"] > 0:
            # Quantised disparity: inverse depth in steps of depth_resolution (1/m).
            step = opts["depth_resolution"]
            with np.errstate(divide="ignore"):
                inv = np.round(np.where(z > 0, 1.0 / np.maximum(z, 1e-9), 0.0) / step) * step
                z = np.where(inv > 0, 1.0 / np.maximum(inv, 1e-12), 0.0)
        valid = hit & (zbuf >= opts["min_range"]) & (zbuf <= opts["max_range"]) & (z > 0)
        depth_mm = np.where(valid, np.clip(np.round(z * DEPTH_SCALE), 1, 65535), 0).astype(np.uint16)
        depth_m = depth_mm.astype(np.float64) / DEPTH_SCALE
        rgb = _shade(prim, face, yaws, colors)
        if opts["rgb_noise"] > 0:
            rgb = rgb + opts["rgb_noise"] * _block_noise(rng_rgb, (H, W), opts["noise_block"])[..., None]
        rgb = np.clip(np.round(rgb), 0, 255).astype(np.uint8)

        _save_png(lap_dir / "rgb" / f"{fid}.png", rgb)
        _save_png(lap_dir / "depth" / f"{fid}.png", depth_mm)
        _save_png(lap_dir / "annotations" / f"{fid}.png", inst)
        ids, counts = np.unique(inst[inst > 0], return_counts=True)
        for oid, n in zip(ids.tolist(), counts.tolist()):
            seen_pixels[oid] += n
            seen_frames[oid] += 1

        dets = _detect(rng_det, inst, depth_m, stats, classes_of, classes, opts, min_pixels)
        doc = {"frame": fid, "detector": "ltc-simulate", "instances": []}
        for cls, score, scores, mask in dets:
            doc["instances"].append({
                "class": cls,
                "score": round(score, 4),
                # Classes absent from the vector have probability 0.
                "scores": {c: round(v, 4) for c, v in scores.items()},
                "mask": rle.encode(mask),
            })
        with open(lap_dir / "detections" / f"{fid}.json", "w", encoding="utf-8") as f:
            json.dump(doc, f, separators=(",", ":"))
            f.write("\n")

    with open(lap_dir / "poses.txt", "w", encoding="utf-8") as f:
        f.write("\n".join(pose_lines) + "\n")
    objects = []
    for oid, o in house.objects.items():
        center, yaw, size = _box_json(*o.box())
        objects.append({
            "id": oid, "class": o.cls, "center": center, "yaw": yaw, "size": size,
            "seen_pixels": int(seen_pixels[oid]), "seen_frames": int(seen_frames[oid]),
            "room": house.rooms[o.room].kind,
        })
    # One object per line: readable and diffable between laps.
    with open(lap_dir / "ground_truth.json", "w", encoding="utf-8") as f:
        f.write('{\n"format": "ltc-ground-truth/1",\n"lap": %d,\n"objects": [\n' % lap)
        f.write(",\n".join(json.dumps(o) for o in objects))
        f.write('\n],\n"changes": %s\n}\n' % json.dumps(changes))
    total = 0
    for root, _, files in os.walk(lap_dir):
        total += sum(os.path.getsize(os.path.join(root, name)) for name in files)
    return {"bytes": total}

"""Furniture models: each object is a few boxes ("parts") in its own frame, so that masks and
depth see the background through the gaps (a chair is a seat, 4 legs and a back of posts and
rails; a table a top and 4 legs). Object frame: x = front (the side facing the room), y = left,
z up from the object's base. A part: (offset (3,), size (3,), colour (3,) or None = the object's
colour)."""

from __future__ import annotations

import math

import numpy as np

CLASS_COLOR = {
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
WALL_COLOR = (214, 208, 196)
CABINET_COLOR = (122, 88, 62)
DARK = (48, 44, 40)
WOOD = (132, 92, 56)
SKY = (236, 236, 240)
FLOOR_COLOR = {
    "living": (166, 126, 86),
    "living_dining": (166, 126, 86),
    "kitchen": (192, 192, 186),
    "bedroom": (150, 112, 76),
    "bathroom": (202, 212, 216),
    "study": (158, 120, 82),
}


def part(offset, size, color=None):
    return (np.array(offset, dtype=np.float64), np.array(size, dtype=np.float64), color)


def parts_aabb(parts):
    lo = np.min([o - s / 2 for o, s, _ in parts], axis=0)
    hi = np.max([o + s / 2 for o, s, _ in parts], axis=0)
    return lo, hi


def recenter(parts):
    """Shift parts so that their XY bounding box is centred on the origin and the base is z = 0."""
    lo, hi = parts_aabb(parts)
    shift = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
    return [(o - shift, s, c) for o, s, c in parts]


def table_parts(rng, length, width, height=0.75):
    top = 0.04
    leg = 0.06
    parts = [part((0, 0, height - top / 2), (width, length, top))]
    for sx in (-1, 1):
        for sy in (-1, 1):
            parts.append(
                part(
                    (sx * (width / 2 - leg / 2 - 0.03), sy * (length / 2 - leg / 2 - 0.03), (height - top) / 2),
                    (leg, leg, height - top),
                )
            )
    return parts


def chair_parts(rng):
    w = float(rng.uniform(0.42, 0.5))
    h, leg, st = 0.45, 0.04, 0.05
    parts = [part((0, 0, h - st / 2), (w, w, st))]
    for sx in (-1, 1):
        for sy in (-1, 1):
            parts.append(part((sx * (w / 2 - leg / 2), sy * (w / 2 - leg / 2), (h - st) / 2), (leg, leg, h - st)))
    bh = float(rng.uniform(0.4, 0.5))
    bx = -w / 2 + leg / 2
    for sy in (-1, 1):
        parts.append(part((bx, sy * (w / 2 - leg / 2), h + bh / 2), (leg, leg, bh)))
    parts.append(part((bx, 0, h + bh - 0.04), (leg, w, 0.08)))  # top rail
    parts.append(part((bx, 0, h + bh * 0.45), (0.03, w - 2 * leg, 0.05)))  # middle rail
    return parts


def armchair_parts(rng):
    w, d = float(rng.uniform(0.75, 0.9)), float(rng.uniform(0.75, 0.85))
    parts = []
    for sx in (-1, 1):
        for sy in (-1, 1):
            parts.append(part((sx * (d / 2 - 0.06), sy * (w / 2 - 0.06), 0.06), (0.05, 0.05, 0.12), DARK))
    parts.append(part((0, 0, 0.26), (d, w, 0.28)))
    parts.append(part((-d / 2 + 0.1, 0, 0.6), (0.2, w, 0.4)))
    for sy in (-1, 1):
        parts.append(part((0.1, sy * (w / 2 - 0.08), 0.5), (d - 0.2, 0.16, 0.2)))
    return parts


def couch_parts(rng):
    L, D = float(rng.uniform(1.7, 2.2)), float(rng.uniform(0.85, 0.95))
    parts = []
    for sx in (-1, 1):
        for sy in (-1, 1):
            parts.append(part((sx * (D / 2 - 0.06), sy * (L / 2 - 0.06), 0.05), (0.06, 0.06, 0.1), DARK))
    parts.append(part((0, 0, 0.25), (D, L, 0.3)))
    parts.append(part((-D / 2 + 0.11, 0, 0.625), (0.22, L, 0.45)))
    for sy in (-1, 1):
        parts.append(part((0.11, sy * (L / 2 - 0.09), 0.5), (D - 0.22, 0.18, 0.2)))
    return parts


def bed_parts(rng):
    L, W = float(rng.uniform(1.95, 2.1)), float(rng.uniform(1.4, 1.8))
    parts = []
    for sx in (-1, 1):
        for sy in (-1, 1):
            parts.append(part((sx * (L / 2 - 0.06), sy * (W / 2 - 0.06), 0.06), (0.08, 0.08, 0.12), WOOD))
    parts.append(part((0, 0, 0.245), (L, W, 0.25), WOOD))
    parts.append(part((0.015, 0, 0.48), (L - 0.06, W - 0.06, 0.22)))
    parts.append(part((-L / 2 + 0.03, 0, 0.525), (0.06, W, 1.05), WOOD))
    parts.append(part((-L / 2 + 0.26, 0, 0.64), (0.32, W * 0.7, 0.1), (240, 240, 236)))
    return parts


def tv_parts(rng):
    w = float(rng.uniform(0.9, 1.3))
    h = w * 0.58
    return [
        part((0, 0, 0.12 + h / 2), (0.05, w, h)),
        part((0, 0, 0.07), (0.04, 0.08, 0.1), DARK),
        part((0, 0, 0.01), (0.22, 0.4, 0.02), DARK),
    ]


def fridge_parts(rng):
    H = float(rng.uniform(1.7, 1.85))
    return [
        part((0, 0, H / 2), (0.7, 0.75, H)),
        part((0.35 + 0.035, 0.3, H * 0.62), (0.03, 0.03, 0.6), (150, 150, 155)),
    ]


def oven_parts(rng):
    return [
        part((0, 0, 0.425), (0.6, 0.6, 0.85)),
        part((0.3 + 0.035, 0, 0.76), (0.03, 0.45, 0.03), (170, 170, 175)),
        part((-0.25, 0, 0.91), (0.1, 0.6, 0.12)),
    ]


def basin_parts(z0=0.0):
    return [
        part((0, 0, z0 + 0.01), (0.42, 0.55, 0.02)),
        part((0.195, 0, z0 + 0.1), (0.03, 0.55, 0.18)),
        part((-0.195, 0, z0 + 0.1), (0.03, 0.55, 0.18)),
        part((0, 0.26, z0 + 0.1), (0.36, 0.03, 0.18)),
        part((0, -0.26, z0 + 0.1), (0.36, 0.03, 0.18)),
        part((-0.245, 0, z0 + 0.15), (0.04, 0.04, 0.3), (170, 170, 175)),
        part((-0.175, 0, z0 + 0.285), (0.14, 0.03, 0.03), (170, 170, 175)),
    ]


def sink_pedestal_parts(rng):
    return basin_parts(0.68) + [part((0, 0, 0.34), (0.16, 0.16, 0.68))]


def toilet_parts(rng):
    return [
        part((0.05, 0, 0.125), (0.3, 0.24, 0.25)),
        part((0.06, 0, 0.325), (0.48, 0.36, 0.15)),
        part((-0.22, 0, 0.6), (0.18, 0.42, 0.4)),
    ]


def plant_parts(rng, scale=None):
    s = float(rng.uniform(0.8, 1.3)) if scale is None else scale
    return [
        part((0, 0, 0.14 * s), (0.3 * s, 0.3 * s, 0.28 * s), (168, 84, 44)),
        part((0, 0, 0.28 * s + 0.125 * s), (0.04, 0.04, 0.25 * s), (40, 90, 40)),
        part((0, 0, 0.53 * s + 0.225 * s), (0.5 * s, 0.5 * s, 0.45 * s)),
    ]


def small_parts(rng, cls):
    if cls == "cup":
        return [part((0, 0, 0.05), (0.08, 0.08, 0.1)), part((0.05, 0, 0.05), (0.02, 0.02, 0.06))]
    if cls == "bowl":
        return [part((0, 0, 0.035), (0.16, 0.16, 0.07))]
    if cls == "book":
        return [part((0, 0, 0.0175), (0.17, 0.24, 0.035))]
    if cls == "bottle":
        return [part((0, 0, 0.1), (0.075, 0.075, 0.2)), part((0, 0, 0.245), (0.03, 0.03, 0.09))]
    if cls == "laptop":
        return [
            part((0, 0, 0.01), (0.24, 0.33, 0.02)),
            part((-0.114, 0, 0.13), (0.012, 0.33, 0.22), (40, 42, 48)),
        ]
    raise ValueError(cls)


def item_members(rng, kind, params, vary=None):
    """Members of a furniture item in its group frame: (cls | None, parts, (x, y, yaw), base_z,
    surface). cls None is structure (a cabinet: drawn, no class); surface: it holds small things.
    vary(parts) -> parts changes the size of each object (None: as modelled)."""
    if vary is None:
        def vary(parts):
            return parts
    if kind in ("dining", "desk"):
        if kind == "dining":
            L, W = float(rng.uniform(1.2, 1.5)), float(rng.uniform(0.75, 0.88))
        else:
            L, W = float(rng.uniform(1.0, 1.3)), float(rng.uniform(0.6, 0.7))
        table = vary(recenter(table_parts(rng, L, W)))
        lo, hi = parts_aabb(table)
        W, L = float(hi[0] - lo[0]), float(hi[1] - lo[1])  # as modelled, or as varied
        members = [("dining table", table, (0.0, 0.0, 0.0), 0.0, True)]
        for k in range(params.get("end_chairs", 0)):
            chair = vary(recenter(chair_parts(rng)))
            d = parts_aabb(chair)[1][0] - parts_aabb(chair)[0][0]
            sy = 1 if k == 0 else -1
            # A chair at an end of the table, facing it (its front, +x, points at the table).
            members.append(("chair", chair, (0.0, sy * (L / 2 + 0.06 + d / 2), -sy * math.pi / 2), 0.0, False))
        n_side = params.get("side_chairs", 0)
        for k in range(n_side):
            chair = vary(recenter(chair_parts(rng)))
            d = parts_aabb(chair)[1][0] - parts_aabb(chair)[0][0]
            y = (k + 0.5) / n_side * L - L / 2
            members.append(("chair", chair, (W / 2 + 0.06 + d / 2, y, math.pi), 0.0, False))
        return members
    simple = {
        "couch": ("couch", couch_parts),
        "armchair": ("chair", armchair_parts),
        "bed": ("bed", bed_parts),
        "fridge": ("refrigerator", fridge_parts),
        "oven": ("oven", oven_parts),
        "toilet": ("toilet", toilet_parts),
        "sink_pedestal": ("sink", sink_pedestal_parts),
        "plant": ("potted plant", plant_parts),
        "plant_small": ("potted plant", lambda r: plant_parts(r, float(r.uniform(0.6, 0.8)))),
    }
    if kind in simple:
        cls, model = simple[kind]
        return [(cls, vary(recenter(model(rng))), (0.0, 0.0, 0.0), 0.0, False)]
    if kind == "tv":
        tv = vary(recenter(tv_parts(rng)))
        tv_w = parts_aabb(tv)[1][1] - parts_aabb(tv)[0][1]
        # Room beside the tv for a thing or two on the cabinet.
        cab = [part((0, 0, 0.25), (0.45, tv_w + float(rng.uniform(0.7, 1.0)), 0.5), CABINET_COLOR)]
        return [(None, cab, (0.0, 0.0, 0.0), 0.0, True), ("tv", tv, (-0.08, 0.0, 0.0), 0.5, False)]
    if kind == "nightstand":
        return [(None, [part((0, 0, 0.275), (0.4, 0.45, 0.55), CABINET_COLOR)], (0.0, 0.0, 0.0), 0.0, True)]
    if kind == "side_table":
        return [(None, [part((0, 0, 0.275), (0.5, 0.5, 0.55), WOOD)], (0.0, 0.0, 0.0), 0.0, True)]
    if kind == "bookcase":
        return [(None, [part((0, 0, 0.9), (0.35, 0.9, 1.8), CABINET_COLOR)], (0.0, 0.0, 0.0), 0.0, False)]
    if kind == "sink_counter":
        cab = [part((0, 0, 0.36), (0.6, 0.8, 0.72), CABINET_COLOR)]
        return [(None, cab, (0.0, 0.0, 0.0), 0.0, False), ("sink", vary(recenter(basin_parts())), (0.0, 0.0, 0.0), 0.72, False)]
    raise ValueError(kind)

"""A house: rooms in a grid with doorways on the robot's way, walls, floors, cabinets, and the
furniture placed along the walls (leaving each room's middle and the ways to its doors free)."""

from __future__ import annotations

import math

import numpy as np

from ltc_cli.tools.simulate.furniture import (
    CLASS_COLOR, FLOOR_COLOR, WALL_COLOR, item_members, parts_aabb, recenter, small_parts,
)
from ltc_cli.tools.simulate.scene import (
    DOOR_HEIGHT, DOOR_WIDTH, MOVABLE, ROOM_KINDS, SCENE_LAYOUT, WALL_HEIGHT, WALL_NORMALS,
    WALL_THICKNESS, Room, SceneObject, Surface, inside, overlap, rect, rot2,
)


class House:
    """Rooms, walls, structure (cabinets: no class), surfaces and the objects of one lap."""

    def __init__(self, scene: str, rng: np.random.Generator, size_rng: np.random.Generator | None = None,
                 size_variation: float = 0.0):
        self.scene = scene
        self.rng = rng
        self.size_rng = size_rng  # draws the size variation, so the house's own draws stay the same
        self.size_variation = size_variation
        self.rooms: list[Room] = []
        self.order: list[int] = []  # the robot's room order
        self.door_list: list[tuple] = []  # (room a, side in a, room b, side in b, along)
        self.structure: list[tuple] = []  # (center (3,), yaw, size (3,), colour)
        self.surfaces: list[Surface] = []
        self.objects: dict[int, SceneObject] = {}
        self.next_id = 1
        self._layout()
        self._walls()
        for room in self.rooms:
            self._furnish(room)

    # -- rooms, doors, walls ---------------------------------------------------------------

    def _layout(self):
        rows = SCENE_LAYOUT[self.scene]
        rng = self.rng
        sizes = [
            [np.array(ROOM_KINDS[k]["size"]) + rng.uniform(-0.25, 0.25, 2) for k in row] for row in rows
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
                room = Room(len(self.rooms), kind, x + half, y + half, x + w - half, y + depth - half, ())
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
            kind = ROOM_KINDS[room.kind]
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
                 FLOOR_COLOR[room.kind])
            )

    def _wall_box(self, horizontal, fixed, a, b, z0, z1):
        t = WALL_THICKNESS
        if horizontal:
            center, size = ((a + b) / 2, fixed, (z0 + z1) / 2), (b - a, t, z1 - z0)
        else:
            center, size = (fixed, (a + b) / 2, (z0 + z1) / 2), (t, b - a, z1 - z0)
        self.structure.append((np.array(center), 0.0, np.array(size), WALL_COLOR))

    # -- furniture ---------------------------------------------------------------------------

    def floor_blocked(self, room, exclude=None):
        polys = list(room.structure)
        for o in self.objects.values():
            if o.room == room.index and o.support is None and o.id != exclude:
                polys.append(o.footprint())
        return polys

    def place_on_wall(self, room, depth, width, sides, blocked, tries=80, margin=0.1):
        """A spot (center_xy (2,), yaw) for a footprint depth x width with its back to a wall.

        The footprint's local x (depth) points into the room. None when nothing fits.
        """
        rng = self.rng
        keepout = room.keepout()
        sides = list(range(4)) if sides is None else [room.big_side] if sides == "big" else list(sides)
        for _ in range(tries):
            side = sides[int(rng.integers(len(sides)))]
            n = np.array(WALL_NORMALS[side])
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
            poly = rect(center, yaw, (depth, width))
            if not inside(poly, room.x0, room.y0, room.x1, room.y1):
                continue
            if any(overlap(poly, k) for k in keepout):
                continue
            grown = rect(center, yaw, (depth + 2 * margin, width + 2 * margin))
            if any(overlap(grown, b) for b in blocked):
                continue
            return center, yaw
        return None

    def add_object(self, cls, room, parts, pos_xy, base_z, yaw, support=None, color=None):
        base = np.array(CLASS_COLOR[cls], dtype=np.float64)
        if color is None:
            color = tuple(int(v) for v in np.clip(base * float(self.rng.uniform(0.85, 1.15)), 0, 255))
        obj = SceneObject(
            self.next_id, cls, room.index, parts,
            np.array([pos_xy[0], pos_xy[1], base_z], dtype=np.float64), float(yaw), color,
            cls in MOVABLE, support,
        )
        self.objects[obj.id] = obj
        self.next_id += 1
        return obj

    def _surface_of_parts(self, room, parts, center_xy, yaw, base_z):
        lo, hi = parts_aabb(parts)
        surf = Surface(np.array(center_xy, dtype=np.float64), float(yaw), (hi - lo)[:2].copy(),
                        base_z + hi[2], room.index)
        self.surfaces.append(surf)
        return len(self.surfaces) - 1

    def _furnish(self, room):
        for kind, sides, params in ROOM_KINDS[room.kind]["items"]:
            self._place_item(room, kind, sides, params)


    def _place_item(self, room, kind, sides, params):
        members = item_members(self.rng, kind, params, self.vary)
        # Footprint of the group in its frame, then centred.
        polys = []
        for cls, parts, (x, y, yaw), _, _ in members:
            lo, hi = parts_aabb(parts)
            polys.append(rect(np.array([x, y]) + rot2(yaw) @ ((lo + hi)[:2] / 2), yaw, (hi - lo)[:2]))
        pts = np.concatenate(polys)
        gmin, gmax = pts.min(axis=0), pts.max(axis=0)
        gc = (gmin + gmax) / 2
        spot = self.place_on_wall(room, gmax[0] - gmin[0], gmax[1] - gmin[1], sides, self.floor_blocked(room))
        if spot is None:
            return  # no room for it: the house simply has one item less
        center, gyaw = spot
        R = rot2(gyaw)
        surface_index = None  # the surface of this item (table top, cabinet top) if it has one
        for cls, parts, (x, y, yaw), base_z, surface in members:
            pos = center + R @ (np.array([x, y]) - gc)
            wyaw = gyaw + yaw
            if cls is None:
                # Structure (no class): drawn like walls, blocks the floor, may hold things.
                lo, hi = parts_aabb(parts)
                for o, s, c in parts:
                    cw = pos + rot2(wyaw) @ o[:2]
                    self.structure.append((np.array([cw[0], cw[1], base_z + o[2]]), wyaw, s.copy(), c))
                room.structure.append(rect(pos, wyaw, (hi - lo)[:2]))
                if surface:
                    surface_index = self._surface_of_parts(room, parts, pos, wyaw, base_z)
            else:
                # A member above the floor stands on the item's surface (a tv on its cabinet).
                support = surface_index if (base_z > 0 and surface_index is not None) else None
                self.add_object(cls, room, parts, pos, base_z, wyaw, support=support)
                if surface:
                    surface_index = self._surface_of_parts(room, parts, pos, wyaw, base_z)
        for cls in params.get("small", []):
            if surface_index is not None:
                self.place_small(cls, surface_index)

    def place_small(self, cls, surface_index, tries=60, exclude=None):
        """Put a new (or, with ``exclude`` = an object, that object) small object on a surface."""
        surf = self.surfaces[surface_index]
        parts = self.vary(recenter(small_parts(self.rng, cls))) if exclude is None else exclude.parts
        spot = self.spot_on_surface(self.rng, surface_index, parts, exclude, tries)
        if spot is None or exclude is not None:
            return spot
        return self.add_object(cls, self.rooms[surf.room], parts, spot[0], surf.z, spot[1], support=surface_index)

    def spot_on_surface(self, rng, surface_index, parts, exclude=None, tries=60):
        """A free spot (center_xy (2,), yaw) on a surface for parts, clear of what already stands on
        it (but ``exclude``); None when none was found in ``tries``."""
        surf = self.surfaces[surface_index]
        lo, hi = parts_aabb(parts)
        radius = 0.5 * float(np.hypot(*(hi - lo)[:2]))
        half = surf.size / 2 - radius - 0.03
        if np.any(half <= 0):
            return None
        # What already stands on it (a tv on its cabinet, other small things).
        blocked = [o.footprint(0.03) for o in self.objects.values() if o.support == surface_index and o is not exclude]
        R = rot2(surf.yaw)
        for _ in range(tries):
            local = rng.uniform(-half, half)
            pos = surf.center + R @ local
            yaw = float(rng.uniform(-math.pi, math.pi))
            poly = rect(pos, yaw, (hi - lo)[:2])
            if any(overlap(poly, b) for b in blocked):
                continue
            return pos, yaw
        return None

    def vary(self, parts):
        """parts scaled by a factor in [1 - v, 1 + v] along each axis (v = size_variation: objects of
        one class differ in size); the same parts when v is 0."""
        v = self.size_variation
        if not v:
            return parts
        f = self.size_rng.uniform(1 - v, 1 + v, 3)
        return [(o * f, s * f, c) for o, s, c in parts]

    def primitives(self):
        """Arrays of all boxes: center (P, 3), yaw (P,), size (P, 3), colour (P, 3), owner (P,)
        (object id, 0 = walls, floors and cabinets)."""
        centers, yaws, sizes, colors, owners = [], [], [], [], []
        for c, yaw, s, col in self.structure:
            centers.append(c), yaws.append(yaw), sizes.append(s), colors.append(col), owners.append(0)
        for obj in self.objects.values():
            R = rot2(obj.yaw)
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

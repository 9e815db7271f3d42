"""Changes between laps: some objects moved (same id, new pose), some removed and some added (new
ids), as people do between two visits of a robot."""

from __future__ import annotations

import numpy as np

from ltc_cli.tools.simulate.furniture import chair_parts, parts_aabb, plant_parts, recenter
from ltc_cli.tools.simulate.house import House
from ltc_cli.tools.simulate.scene import ADDABLE_FLOOR, SMALL_CLASSES


def change_house(house: House, rng: np.random.Generator, moved_f, removed_f, added_f) -> dict:
    """Move, remove and add objects (in place). Returns {"moved", "removed", "added"} ids."""
    house.rng = rng
    ids = sorted(house.objects)
    n = len(ids)

    def count(f):
        return 0 if f <= 0 or n == 0 else max(1, int(round(f * n)))

    movable = [i for i in ids if house.objects[i].movable]
    rng.shuffle(movable)
    moved, removed, added = [], [], []
    for oid in movable:
        if len(moved) >= count(moved_f):
            break
        if move_object(house, house.objects[oid]):
            moved.append(oid)
    for oid in movable:
        if len(removed) >= count(removed_f):
            break
        if oid not in moved:
            del house.objects[oid]
            removed.append(oid)
    attempts = 0
    while len(added) < count(added_f) and attempts < 20:
        attempts += 1
        if rng.uniform() < 0.5 and house.surfaces:
            cls = SMALL_CLASSES[int(rng.integers(len(SMALL_CLASSES)))]
            obj = house.place_small(cls, int(rng.integers(len(house.surfaces))))
        else:
            room = house.rooms[int(rng.integers(len(house.rooms)))]
            cls = ADDABLE_FLOOR[int(rng.integers(len(ADDABLE_FLOOR)))]
            parts = house.vary(recenter(chair_parts(rng) if cls == "chair" else plant_parts(rng)))
            lo, hi = parts_aabb(parts)
            spot = house.place_on_wall(room, hi[0] - lo[0], hi[1] - lo[1], None, house.floor_blocked(room))
            obj = None if spot is None else house.add_object(cls, room, parts, spot[0], 0.0, spot[1])
        if obj is not None:
            added.append(obj.id)
    return {"moved": sorted(moved), "removed": sorted(removed), "added": sorted(added)}


def move_object(house: House, obj) -> bool:
    """Put obj somewhere else (at least 0.3 m away: on another surface for a small thing, by another
    wall of its room for furniture); False when no place was found in 10 tries."""
    old = obj.box()[0]
    for _ in range(10):
        if obj.support is not None:
            surface_index = int(house.rng.integers(len(house.surfaces)))
            spot = house.place_small(obj.cls, surface_index, exclude=obj)
        else:
            room = house.rooms[obj.room]
            lo, hi = parts_aabb(obj.parts)
            spot = house.place_on_wall(room, hi[0] - lo[0], hi[1] - lo[1], None,
                                       house.floor_blocked(room, exclude=obj.id))
            surface_index = None
        if spot is None:
            continue
        pos, yaw = spot
        if np.hypot(*(pos - old[:2])) < 0.3:
            continue
        obj.pos = np.array([pos[0], pos[1], 0.0 if surface_index is None else house.surfaces[surface_index].z])
        obj.yaw = float(yaw)
        if surface_index is not None:
            obj.support = surface_index
            obj.room = house.surfaces[surface_index].room
        return True
    return False

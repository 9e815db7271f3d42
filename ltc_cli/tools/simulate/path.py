"""The robot's path: the same in every lap. In each room a small loop around the room's free middle
with the camera looking outwards at the furniture along the walls (so every object is seen from
several places, often only in part); from room to room through the doorways."""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

from ltc_cli.tools.simulate.house import House
from ltc_cli.tools.simulate.scene import WALL_THICKNESS

# The OpenCV camera of heading 0 (looking along world +x, level): camera x (right) = world -y,
# camera y (down) = world -z, camera z (forward) = world +x; columns are the camera axes.
_R_LEVEL = Rotation.from_matrix(np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]))


def camera_rotation(heading, pitch, roll) -> np.ndarray:
    """R_world_camera (3, 3) for an OpenCV camera looking along ``heading`` (about world z),
    pitched down by ``pitch`` and rolled by ``roll`` about its optical axis."""
    # Heading about world z, then (intrinsic) pitch down = a negative turn about camera x, then roll
    # about the optical axis.
    R = Rotation.from_euler("z", heading) * _R_LEVEL * Rotation.from_euler("XZ", [-pitch, roll])
    return R.as_matrix()


def camera_path(house: House, rng, frames_per_room, transit_step, height, pitch_deg):
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
        T[:3, :3] = camera_rotation(heading, pitch, roll)
        T[:3, 3] = [xy[0], xy[1], z]
        out.append(T)
    return np.array(out)

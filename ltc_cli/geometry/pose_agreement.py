"""Do a recording's poses fit its depth? Two frames close in time see mostly the same surfaces, so
one frame's depth, moved by the poses into the other camera, must land on the other frame's depth.
Pure numpy.

Poses in another convention than ltc's (``T_world_camera``, camera-to-world, OpenCV camera axes:
x right, y down, z forward; quaternions x y z w) give a map of nonsense without any error. Each
reading in :data:`READINGS` turns the poses as read into the poses had the file meant another
convention; the one under which the frames agree best says what the file holds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from ltc_cli.geometry.camera import backproject, invert_pose, project, transform

#: A point agrees with the other frame when its depth there is within this (m) of the observed one.
TOLERANCE = 0.05
#: An alternative reading is reported when its agreement is at least this many times, and this
#: much more than, the poses' own.
BETTER_RATIO, BETTER_MARGIN = 1.5, 0.2
#: ... and at least this much.
MIN_AGREEMENT = 0.2
#: The poses as given disagree when under this share of points agree although this share of
#: them lands in the other image (the views overlap).
DISAGREE, OVERLAP = 0.05, 0.3

_GL = np.diag([1.0, -1.0, -1.0, 1.0])  # OpenGL camera axes (x right, y up, z backward) -> OpenCV
_BODY = np.eye(4)
_BODY[:3, :3] = [[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]  # OpenCV axes in x-forward, z-up axes


def _w_first(T: np.ndarray) -> np.ndarray:
    """The pose had its quaternion been written w x y z and read as x y z w."""
    a, b, c, d = Rotation.from_matrix(T[:3, :3]).as_quat()  # what the reader took for x, y, z, w
    out = T.copy()
    out[:3, :3] = Rotation.from_quat([b, c, d, a]).as_matrix()
    return out


#: name (the reader option ``-r pose_convention=NAME``) -> (what the file would hold, the poses ltc should
#: have read from it, as a function of the poses read)
READINGS = {
    "inverted": ("world-to-camera poses (ltc reads camera-to-world, T_world_camera)", invert_pose),
    "opengl": ("poses of a camera with OpenGL axes (x right, y up, z backward; ltc's camera has "
               "OpenCV axes: x right, y down, z forward)", lambda T: T @ _GL),
    "x-forward": ("poses of a body with x forward, z up (ROS's base frame; ltc's camera has OpenCV "
                  "axes: x right, y down, z forward)", lambda T: T @ _BODY),
    "w-first": ("quaternions written w x y z (ltc reads x y z w)", _w_first),
}


def agreement(depth_a: np.ndarray, depth_b: np.ndarray, T_world_a: np.ndarray, T_world_b: np.ndarray, intr,
              stride: int = 8, tolerance: float = TOLERANCE) -> tuple[float, float]:
    """(agree, inside): of frame a's depth readings (every ``stride``-th pixel), the share that,
    moved into camera b, land in its image on a reading within ``tolerance``; and the share that
    land in its image in front of it at all."""
    d = depth_a[stride // 2::stride, stride // 2::stride]
    v, u = np.nonzero(d > 0)
    if not len(v):
        return 0.0, 0.0
    points_a = backproject(u * stride + stride // 2, v * stride + stride // 2, d[v, u], intr)
    points_b = transform(invert_pose(T_world_b) @ T_world_a, points_a)
    with np.errstate(invalid="ignore"):
        ub, vb, zb = project(points_b, intr)
    h, w = depth_b.shape
    inside = (zb > 0.1) & (ub >= 0) & (ub < w) & (vb >= 0) & (vb < h)
    seen = np.zeros(len(zb))
    seen[inside] = depth_b[vb[inside].astype(int), ub[inside].astype(int)]
    agree = inside & (seen > 0) & (np.abs(seen - zb) < tolerance)
    return float(agree.mean()), float(inside.mean())


@dataclass
class PoseVerdict:
    agree: dict  # reading ("as given" or a READINGS name) -> median agreement over the pairs
    inside: float  # median share landing in the other image, as given
    better: str | None  # the READINGS name under which the frames agree clearly better, if any

    @property
    def disagree(self) -> bool:
        """The views overlap, yet the poses as given do not put one frame's depth on the other's."""
        return self.better is None and self.agree["as given"] < DISAGREE and self.inside >= OVERLAP


def judge_poses(pairs: list) -> PoseVerdict | None:
    """The poses' agreement as given and under each of READINGS, over ``pairs`` of frames close in
    time, each (depth_a, depth_b, T_world_a, T_world_b, intrinsics); None without pairs."""
    if not pairs:
        return None
    readings = {"as given": lambda T: T, **{name: fn for name, (_, fn) in READINGS.items()}}
    agree, inside = {}, []
    for name, fn in readings.items():
        shares = [agreement(da, db, fn(Ta), fn(Tb), intr) for da, db, Ta, Tb, intr in pairs]
        agree[name] = float(np.median([s[0] for s in shares]))
        if name == "as given":
            inside = [s[1] for s in shares]
    given = agree["as given"]
    best = max(READINGS, key=lambda name: agree[name])
    ok = agree[best] >= max(BETTER_RATIO * given, given + BETTER_MARGIN, MIN_AGREEMENT)
    return PoseVerdict(agree, float(np.median(inside)), best if ok else None)

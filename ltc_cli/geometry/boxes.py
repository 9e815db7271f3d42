"""Pure numpy geometry of Z-oriented boxes, poses and pinhole cameras.

Conventions (DESIGN.md section 2): map frame right-handed with z up; camera frame OpenCV (x right,
y down, z forward); poses are ``T_world_camera`` (camera-to-world). A box is ``center (3,)``,
``yaw`` about z in [-pi/2, pi/2), ``size (3,)`` along the box's own x, y and the world z. Its
``corners (8, 3)`` are the bottom ring 0-3 counter-clockwise seen from above, then the top ring 4-7
above them in the same order.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

HALF_PI = np.pi / 2

# Bottom ring counter-clockwise seen from +z, then the top ring: unit offsets in the box frame.
CORNER_SIGNS = np.array(
    [
        [-1, -1, -1],
        [+1, -1, -1],
        [+1, +1, -1],
        [-1, +1, -1],
        [-1, -1, +1],
        [+1, -1, +1],
        [+1, +1, +1],
        [-1, +1, +1],
    ],
    dtype=np.float64,
)

# Edges of a box grouped by the box axis they run along: x, y, z.
EDGES_BY_AXIS = (
    np.array([[0, 1], [3, 2], [4, 5], [7, 6]]),
    np.array([[1, 2], [0, 3], [5, 6], [4, 7]]),
    np.array([[0, 4], [1, 5], [2, 6], [3, 7]]),
)

# Vertex permutations for the 4 cyclic shifts of the rings (same shift for bottom and top ring):
# SHIFTS[k][i] is the vertex of the other box that corresponds to vertex i of this one.
SHIFTS = np.array(
    [[(i + k) % 4 for i in range(4)] + [4 + (i + k) % 4 for i in range(4)] for k in range(4)]
)


def wrap_yaw(yaw):
    """Yaw in [-pi/2, pi/2): a Z-oriented box is the same box after a half turn."""
    return np.mod(np.asarray(yaw, dtype=np.float64) + HALF_PI, np.pi) - HALF_PI


def rot_z(yaw) -> np.ndarray:
    """R (..., 3, 3) rotating by ``yaw`` about z."""
    yaw = np.asarray(yaw, dtype=np.float64)
    c, s = np.cos(yaw), np.sin(yaw)
    R = np.zeros(yaw.shape + (3, 3))
    R[..., 0, 0], R[..., 0, 1] = c, -s
    R[..., 1, 0], R[..., 1, 1] = s, c
    R[..., 2, 2] = 1.0
    return R


def box_corners(center, yaw, size) -> np.ndarray:
    """Corners of boxes: center (..., 3), yaw (...,), size (..., 3) -> corners (..., 8, 3).

    Corner k is ``center + R(yaw) (CORNER_SIGNS[k] * size / 2)``. The rotated ring is computed
    once for the four corners of the bottom ring, from the products c hx, s hy, s hx, c hy times
    the corners' signs (a sign flip is exact, so these are the very operations of rotating each
    signed half size), and shared by the top ring: the same bits as rotating all eight on
    (..., 8, 3) temporaries, several times faster on 100,000 boxes (tests/test_geometry.py).
    """
    center = np.asarray(center, dtype=np.float64)
    size = np.asarray(size, dtype=np.float64)
    yaw = np.asarray(yaw, dtype=np.float64)
    half = size / 2.0
    c, s = np.cos(yaw)[..., None], np.sin(yaw)[..., None]
    hx, hy, hz = half[..., 0, None], half[..., 1, None], half[..., 2, None]
    sx, sy = CORNER_SIGNS[:4, 0], CORNER_SIGNS[:4, 1]
    x = (c * hx) * sx - (s * hy) * sy  # x = c lx - s ly, y = s lx + c ly
    y = (s * hx) * sx + (c * hy) * sy
    x, y = x + center[..., 0, None], y + center[..., 1, None]
    z0, z1 = -hz + center[..., 2, None], hz + center[..., 2, None]
    out = np.empty(np.broadcast_shapes(x.shape, z0.shape)[:-1] + (8, 3))
    out[..., :4, 0], out[..., 4:, 0] = x, x
    out[..., :4, 1], out[..., 4:, 1] = y, y
    out[..., :4, 2], out[..., 4:, 2] = z0, z1
    return out


@dataclass
class Boxes:
    """M Z-oriented boxes as arrays: center (M, 3), yaw (M,), size (M, 3), visible (M, 8) bool."""

    center: np.ndarray
    yaw: np.ndarray
    size: np.ndarray
    visible: np.ndarray

    def __post_init__(self):
        self._corners = None

    @property
    def corners(self) -> np.ndarray:
        """(M, 8, 3) corners in the map frame."""
        if self._corners is None:
            self._corners = box_corners(self.center, self.yaw, self.size)
        return self._corners

    def __len__(self) -> int:
        return len(self.yaw)

    def row(self, k: int, defined: bool = False) -> "Box":
        """Box k as a single :class:`Box` (copies), with its Defined flag."""
        return Box(self.center[k].copy(), float(self.yaw[k]), self.size[k].copy(), self.visible[k].copy(), defined)

    def take(self, idx) -> "Boxes":
        out = Boxes(self.center[idx], self.yaw[idx], self.size[idx], self.visible[idx])
        if self._corners is not None:  # already computed: keep them
            out._corners = self._corners[idx]
        return out


def convex_hull_xy(xy: np.ndarray) -> np.ndarray:
    """Counter-clockwise hull vertices (H, 2) of points xy (N, 2); degenerate sets give 1-2 points."""
    xy = np.asarray(xy, dtype=np.float64)
    if len(xy) == 0:
        raise ValueError("no points")
    d = xy - xy.mean(axis=0)
    # The 2x2 scatter says at once whether the set is (nearly) a line: a flat face seen edge-on
    # from above. qhull would refuse it, and its exception costs more than this test.
    evals, evecs = np.linalg.eigh(d.T @ d)
    if len(xy) >= 3 and evals[0] > 1e-12 * max(evals[1], 1e-300):
        # scipy.spatial is imported here (a no-op after the first call): at the top it would cost
        # every command that loads a map ~0.25 s of start-up.
        from scipy.spatial import ConvexHull, QhullError

        try:
            hull = ConvexHull(xy)
            return xy[hull.vertices]  # qhull gives 2-D hulls counter-clockwise
        except QhullError:
            pass
    # Collinear or tiny sets: the two extreme points along the principal direction.
    t = d @ evecs[:, 1]
    return xy[[int(np.argmin(t)), int(np.argmax(t))]]


def min_area_rect(xy: np.ndarray):
    """Exact minimum-area enclosing rectangle of points xy (N, 2) by rotating calipers.

    The optimal rectangle has one side collinear with a hull edge (Freeman & Shapira 1975), so
    trying each hull edge direction is exact. Returns (center_xy (2,), yaw, (sx, sy)), yaw in
    [-pi/2, pi/2) and sx measured along the yaw direction.
    """
    hull = convex_hull_xy(xy)
    if len(hull) == 1:
        return hull[0].copy(), 0.0, (0.0, 0.0)
    edges = np.roll(hull, -1, axis=0) - hull
    angles = np.arctan2(edges[:, 1], edges[:, 0])
    angles = angles[np.hypot(edges[:, 0], edges[:, 1]) > 1e-12]
    if angles.size == 0:  # every point at one place
        return hull[0].copy(), 0.0, (0.0, 0.0)
    c, s = np.cos(angles)[:, None], np.sin(angles)[:, None]
    u = hull[None, :, 0] * c + hull[None, :, 1] * s  # coordinates along each candidate axis
    v = -hull[None, :, 0] * s + hull[None, :, 1] * c
    umin, umax = u.min(axis=1), u.max(axis=1)
    vmin, vmax = v.min(axis=1), v.max(axis=1)
    area = (umax - umin) * (vmax - vmin)
    k = int(np.argmin(area))
    a = float(angles[k])
    uc, vc = (umin[k] + umax[k]) / 2, (vmin[k] + vmax[k]) / 2
    center = np.array([uc * np.cos(a) - vc * np.sin(a), uc * np.sin(a) + vc * np.cos(a)])
    # A half turn gives the same rectangle with the same sides.
    return center, float(wrap_yaw(a)), (float(umax[k] - umin[k]), float(vmax[k] - vmin[k]))


def fit_box(points_xyz: np.ndarray):
    """Minimum-area Z-oriented box of points (N, 3): (center (3,), yaw, size (3,))."""
    cxy, yaw, (sx, sy) = min_area_rect(points_xyz[:, :2])
    zmin, zmax = float(points_xyz[:, 2].min()), float(points_xyz[:, 2].max())
    center = np.array([cxy[0], cxy[1], (zmin + zmax) / 2])
    return center, yaw, np.array([sx, sy, zmax - zmin])


def align_yaw(yaw_ref, yaw, size):
    """Re-express boxes (yaw, size) with the quarter turn closest to ``yaw_ref``.

    A box with yaw + pi/2 and its x and y sizes swapped is the same box; averaging orientations
    needs both in the representation nearest each other. Works on scalars or arrays; the returned
    yaw is within pi/4 of yaw_ref (not wrapped).
    """
    yaw = np.asarray(yaw, dtype=np.float64)
    size = np.array(size, dtype=np.float64, copy=True)
    k = np.round((yaw - yaw_ref) / HALF_PI).astype(int)
    yaw_aligned = yaw - k * HALF_PI
    odd = (k % 2) == 1
    if np.ndim(odd) == 0:
        if odd:
            size[..., [0, 1]] = size[..., [1, 0]]
    else:
        size[odd, 0], size[odd, 1] = size[odd, 1].copy(), size[odd, 0].copy()
    return yaw_aligned, size




@dataclass
class Box:
    """One Z-oriented box, a row of :class:`Boxes` with its Defined flag: center (3,), yaw, size (3,),
    visible (8,) bool, defined (all three dimensions observed, DESIGN.md 1.1)."""

    center: np.ndarray
    yaw: float
    size: np.ndarray
    visible: np.ndarray
    defined: bool

    def as_boxes(self) -> Boxes:
        return Boxes(self.center[None], np.array([self.yaw]), self.size[None], self.visible[None])

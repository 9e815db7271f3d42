"""Exact ray casting of Z-oriented boxes with a z-buffer, and flat shading.

For each box only the pixels of its projected bounding rectangle are tested (a vectorised slab test
in the box's frame). The ray of pixel (u, v) is ((u - cx) / fx, (v - cy) / fy, 1) in the camera
frame, so its hit parameter is the camera-frame depth Z and back-projection by eq. 1 recovers the
surface point exactly.
"""

from __future__ import annotations

import math

import numpy as np

from ltc_cli.geometry.boxes import EDGES_BY_AXIS, box_corners
from ltc_cli.tools.simulate.furniture import SKY

_ALL_EDGES = np.concatenate(EDGES_BY_AXIS)
_NEAR = 0.05


class Renderer:
    """Ray casting of boxes with a z-buffer, for one camera."""

    def __init__(self, width, height, fx, fy, cx, cy):
        self.W, self.H = width, height
        self.fx, self.fy, self.cx, self.cy = fx, fy, cx, cy
        u = (np.arange(width, dtype=np.float64) - cx) / fx
        v = (np.arange(height, dtype=np.float64) - cy) / fy
        # Ray of pixel (u, v) in the camera frame, with z = 1: its hit parameter is the depth Z.
        self.rays = np.stack(np.broadcast_arrays(u[None, :], v[:, None], np.ones((height, width))), axis=-1)

    def _pixel_bounds(self, cam8):
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
            r = self._pixel_bounds(cam[p])
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


def shade(prim, face, yaws, colors):
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
    rgb[~hit] = SKY
    return rgb

"""A depth sensor's error, measured from its own depth images (``modeling.depth_noise: auto``).

Kinect-class and stereo sensors measure disparity, so their depth error grows with Z^2: the std
is ``K Z^2`` metres, ``K`` being the error at 1 m (Khoshelham & Elberink 2012: about 0.0015-0.002
for a Kinect v1; a RealSense D435 about 0.01). In inverse depth ``w = 1 / Z`` the same error is a
constant ``K`` (``dw = dZ / Z^2``), and a plane's inverse depth is exactly linear in the pixel
coordinates. So each square patch of a depth image gets a plane fitted to its inverse depth by
least squares (eq. 1's pinhole model makes any plane linear in u, v), and the residual's std is
``K`` wherever the patch is flat; a patch over an edge or a curved thing has more.

Indoors a fair share of every view is flat (floor, walls, desk and table tops, doors), so the
low quantile ``QUANTILE`` of the patches' residuals is the flat patches' value, whatever the rest
holds. A stereo sensor's error is smooth over its matching window (several pixels), which a small
patch's plane absorbs; patches a tenth of the image wide hold enough windows to show it.
Measured on the six frames an ingest samples (docs/decisions.md, "A sensor's depth error,
measured"): tum-fr1-rpy (a Kinect v1) 0.0027; tum-fr1-rpy with a smooth error of 0.01 / 0.02 /
0.03 Z^2 added 0.0097 / 0.0184 / 0.0270 (the two errors together: 0.0102 / 0.0201 / 0.0301); the
simulator's sensor (0.005, quantised in disparity) 0.0047-0.0048.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

# Patch side as a share of the image's width: 64 px at 640 (a stereo window is 5-9 px; a smaller
# patch's plane takes up part of its error: 48 px gave 0.0089 for 0.0102, 24 px 0.0062).
PATCH_SHARE = 0.1
MIN_PATCH_PX = 8
# A patch is fitted when this share of its pixels has a reading in DEPTH_RANGE_M.
MIN_VALID_SHARE = 0.9
DEPTH_RANGE_M = (0.3, 6.0)
# The share of patches taken as flat. On tum-fr1-rpy, a cluttered desk seen from 1 m, the 0.3
# quantile already holds edges (0.0072 with 0.005 added, 0.0055 at 0.2); 0.1 measures 8-12 % under
# the errors added.
QUANTILE = 0.2
# Fewer flat-enough patches than this over the sampled frames measure nothing.
MIN_PATCHES = 24


def patch_side(width: int) -> int:
    """Side in pixels of the square patches of an image ``width`` pixels wide."""
    return max(MIN_PATCH_PX, int(round(PATCH_SHARE * width)))


def patch_residuals(depth_m: np.ndarray, side: int | None = None) -> np.ndarray:
    """Residual std (P,), in 1/m, of the inverse depth about the plane fitted to it in each
    ``side`` x ``side`` patch of depth_m (H, W) metres (0 = no reading) that has enough readings."""
    depth = np.asarray(depth_m, dtype=np.float64)
    H, W = depth.shape
    s = patch_side(W) if side is None else int(side)
    ny, nx = H // s, W // s
    if ny == 0 or nx == 0:
        return np.zeros(0)
    z = depth[: ny * s, : nx * s].reshape(ny, s, nx, s).transpose(0, 2, 1, 3).reshape(ny * nx, s * s)
    ok = np.isfinite(z) & (z > DEPTH_RANGE_M[0]) & (z < DEPTH_RANGE_M[1])
    n = ok.sum(axis=1)
    keep = n >= MIN_VALID_SHARE * s * s
    z, ok, n = z[keep], ok[keep], n[keep].astype(np.float64)
    if len(z) == 0:
        return np.zeros(0)
    m = ok.astype(np.float64)
    w = np.where(ok, 1.0 / np.where(ok, z, 1.0), 0.0)
    # Centred coordinates and inverse depth keep the normal equations well conditioned.
    v, u = np.mgrid[0:s, 0:s]
    uv1 = np.stack([u.ravel() - (s - 1) / 2.0, v.ravel() - (s - 1) / 2.0, np.ones(s * s)], axis=1)  # (s*s, 3)
    w_mean = (w * m).sum(axis=1) / n
    wc = (w - w_mean[:, None]) * m  # (P, s*s), 0 where no reading
    A = (m @ (uv1[:, :, None] * uv1[:, None, :]).reshape(s * s, 9)).reshape(-1, 3, 3)  # (P, 3, 3)
    b = wc @ uv1  # (P, 3)
    coef = np.linalg.solve(A, b[..., None])[..., 0]
    ss = np.maximum((wc * wc).sum(axis=1) - (coef * b).sum(axis=1), 0.0)
    return np.sqrt(ss / np.maximum(n - 3.0, 1.0))


def estimate_depth_noise(depth_images: Sequence[np.ndarray]) -> tuple[float | None, int]:
    """(K, patches): the sensor's depth error std at 1 m (error ``K Z^2`` metres) from a few depth
    images (each (H, W) metres, 0 = no reading), and the number of patches it rests on; K is None
    when fewer than MIN_PATCHES could be fitted (too few readings, or images too small)."""
    parts = [patch_residuals(d) for d in depth_images]
    resid = np.concatenate(parts) if parts else np.zeros(0)
    if len(resid) < MIN_PATCHES:
        return None, int(len(resid))
    return float(np.quantile(resid, QUANTILE)), int(len(resid))

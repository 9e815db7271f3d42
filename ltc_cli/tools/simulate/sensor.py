"""The RGB-D sensor: depth and colour images from a rendered frame.

The default sensor is Kinect-like: Gaussian depth noise growing with Z^2, correlated over
noise_block x noise_block pixels (the sensor matches windows of about that size), then quantised in
disparity; readings outside [min_range, max_range] are 0. RGB is the flat shading with a little
block noise, which keeps the PNGs small.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage
from scipy.special import ndtr

from ltc_cli.tools.simulate.raycast import shade

DEPTH_SCALE = 1000.0  # depth PNG units per metre (millimetres)


def block_noise(rng, shape, block):
    """Standard normal noise (H, W) constant over block x block pixels."""
    H, W = shape
    b = max(1, int(block))
    small = rng.standard_normal((-(-H // b), -(-W // b)))
    return np.repeat(np.repeat(small, b, axis=0), b, axis=1)[:H, :W]


def depth_image(rng, zbuf, hit, opts, dropout=None, rng_extra=None) -> np.ndarray:
    """Depth PNG (H, W) uint16 in millimetres (0 = no reading) from the true Z (H, W) of the hit
    pixels (H, W) bool. dropout (H, W): the probability of no reading per pixel (dark and shiny
    surfaces), or None; flying pixels and dropout draw from rng_extra, so rng's draws stay the
    same."""
    z = np.where(hit, zbuf, 0.0)
    if opts["flying_pixels"] > 0:
        z = flying_pixels(rng_extra, z, hit, opts["flying_pixels"])
    # The true Z plus noise growing with Z^2.
    if opts["depth_noise"] > 0:
        z = z + opts["depth_noise"] * z * z * block_noise(rng, z.shape, opts["noise_block"])
    if opts["depth_resolution"] > 0:
        # Quantised disparity: inverse depth in steps of depth_resolution (1/m).
        step = opts["depth_resolution"]
        with np.errstate(divide="ignore"):
            inv = np.round(np.where(z > 0, 1.0 / np.maximum(z, 1e-9), 0.0) / step) * step
            z = np.where(inv > 0, 1.0 / np.maximum(inv, 1e-12), 0.0)
    valid = hit & (zbuf >= opts["min_range"]) & (zbuf <= opts["max_range"]) & (z > 0)
    if dropout is not None:
        valid &= ~holes(rng_extra, dropout)
    return np.where(valid, np.clip(np.round(z * DEPTH_SCALE), 1, 65535), 0).astype(np.uint16)


def rgb_image(rng, prim, face, yaws, colors, opts) -> np.ndarray:
    """Colour image (H, W, 3) uint8: flat shading of the hit primitives plus block noise."""
    rgb = shade(prim, face, yaws, colors)
    if opts["rgb_noise"] > 0:
        rgb = rgb + opts["rgb_noise"] * block_noise(rng, prim.shape, opts["noise_block"])[..., None]
    return np.clip(np.round(rgb), 0, 255).astype(np.uint8)


def flying_pixels(rng, z, hit, share):
    """Depth edges as a time-of-flight or stereo sensor sees them: a share of the pixels where the
    3 x 3 neighbourhood spans a jump (over 0.1 m + 5 % of the depth) reads a mix of the near and far
    surface, a point floating in the air between them. z (H, W) metres, 0 off hit."""
    near = ndimage.minimum_filter(np.where(hit, z, np.inf), size=3, mode="nearest")
    near = np.where(np.isfinite(near), near, z)  # no hit around: no edge
    far = ndimage.maximum_filter(z, size=3, mode="nearest")
    edge = hit & (far - near > 0.1 + 0.05 * z)
    pick = edge & (rng.uniform(size=z.shape) < share)
    t = rng.uniform(0.15, 0.85, size=z.shape)
    return np.where(pick, near + t * (far - near), z)


def holes(rng, dropout):
    """Where a reading is missing (H, W) bool: a smooth random field (blobs ~10 pixels across at 640,
    like the patches a sensor loses on a dark or shiny surface) under the per-pixel probability."""
    H, W = dropout.shape
    field = ndimage.gaussian_filter(rng.standard_normal((H, W)), sigma=max(1.0, 6.0 * W / 640.0))
    u = ndtr(field / max(1e-12, float(field.std())))
    return u < dropout


def dropout_map(prim, colors, shiny_prims, opts):
    """The probability of no reading per pixel (H, W): dark_dropout on surfaces whose colour is dark
    (luminance under 70 of 255: a tv screen, black legs), shiny_dropout on shiny ones (screens,
    steel, glass: shiny_prims (P,) bool), both where both; None when both options are 0."""
    if not (opts["dark_dropout"] > 0 or opts["shiny_dropout"] > 0):
        return None
    lum = colors @ np.array([0.299, 0.587, 0.114])
    keep = (1 - opts["dark_dropout"] * (lum < 70)) * (1 - opts["shiny_dropout"] * shiny_prims)
    return np.where(prim >= 0, 1 - keep[np.maximum(prim, 0)], 0.0)

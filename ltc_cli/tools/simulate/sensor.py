"""The RGB-D sensor: depth and colour images from a rendered frame.

The default sensor is Kinect-like: Gaussian depth noise growing with Z^2, correlated over
noise_block x noise_block pixels (the sensor matches windows of about that size), then quantised in
disparity; readings outside [min_range, max_range] are 0. RGB is the flat shading with a little
block noise, which keeps the PNGs small.
"""

from __future__ import annotations

import numpy as np

from ltc_cli.tools.simulate.raycast import shade

DEPTH_SCALE = 1000.0  # depth PNG units per metre (millimetres)


def block_noise(rng, shape, block):
    """Standard normal noise (H, W) constant over block x block pixels."""
    H, W = shape
    b = max(1, int(block))
    small = rng.standard_normal((-(-H // b), -(-W // b)))
    return np.repeat(np.repeat(small, b, axis=0), b, axis=1)[:H, :W]


def depth_image(rng, zbuf, hit, opts) -> np.ndarray:
    """Depth PNG (H, W) uint16 in millimetres (0 = no reading) from the true Z (H, W) of the hit
    pixels (H, W) bool."""
    # The true Z plus noise growing with Z^2.
    z = np.where(hit, zbuf, 0.0)
    if opts["depth_noise"] > 0:
        z = z + opts["depth_noise"] * z * z * block_noise(rng, z.shape, opts["noise_block"])
    if opts["depth_resolution"] > 0:
        # Quantised disparity: inverse depth in steps of depth_resolution (1/m).
        step = opts["depth_resolution"]
        with np.errstate(divide="ignore"):
            inv = np.round(np.where(z > 0, 1.0 / np.maximum(z, 1e-9), 0.0) / step) * step
            z = np.where(inv > 0, 1.0 / np.maximum(inv, 1e-12), 0.0)
    valid = hit & (zbuf >= opts["min_range"]) & (zbuf <= opts["max_range"]) & (z > 0)
    return np.where(valid, np.clip(np.round(z * DEPTH_SCALE), 1, 65535), 0).astype(np.uint16)


def rgb_image(rng, prim, face, yaws, colors, opts) -> np.ndarray:
    """Colour image (H, W, 3) uint8: flat shading of the hit primitives plus block noise."""
    rgb = shade(prim, face, yaws, colors)
    if opts["rgb_noise"] > 0:
        rgb = rgb + opts["rgb_noise"] * block_noise(rng, prim.shape, opts["noise_block"])[..., None]
    return np.clip(np.round(rgb), 0, 255).astype(np.uint8)

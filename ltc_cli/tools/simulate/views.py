"""What makes the realistic detector's errors look like a real one's: per-class miss rates, misses
of flat-faced things seen at an angle, misses and mislabels that persist over nearby views of one
object (a slowly changing state per object and lap), systematic mislabels (one object taken for
one fixed other class in a share of its views), and CNN-like mask shapes.

The benign detector draws every miss and confusion independently per frame; with these options at
0 this module changes none of its draws.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage
from scipy.special import ndtr, ndtri

from ltc_cli.tools.simulate.drift import smooth_noise

#: Miss-rate multipliers per class (class_miss = 1): large furniture is found more often than the
#: base rate, small things, sinks and screens (dark, reflective, seen edge-on) far less often.
#: "phantom" is a recurring false positive's weight, "person" a person's.
CLASS_MISS = {
    "bed": 0.6, "couch": 0.6, "refrigerator": 0.7, "toilet": 0.8, "chair": 1.0, "potted plant": 1.0,
    "dining table": 1.2, "oven": 1.3, "laptop": 1.5, "cup": 1.6, "bowl": 1.6, "book": 1.6, "bottle": 1.6,
    "tv": 2.0, "sink": 2.0, "phantom": 1.5, "person": 0.5,
}

#: Classes seen well only from the front (their +x side): oblique_miss grows with the angle.
FACING = ("tv", "sink", "laptop")

#: The fixed other class of an object that the detector mislabels systematically.
SYSTEMATIC = {
    "dining table": "book", "chair": "couch", "couch": "bed", "bed": "couch", "tv": "laptop",
    "laptop": "tv", "sink": "toilet", "toilet": "sink", "refrigerator": "oven", "oven": "refrigerator",
    "potted plant": "bottle", "cup": "bowl", "bowl": "cup", "book": "laptop", "bottle": "cup",
}

MISS, CONFUSION, MISLABEL = 0, 1, 2  # the channels of an object's slow state
MASK_GRID = 28  # a Mask R-CNN mask head's resolution


class ViewModel:
    """The per-lap states and fixed traits of every detectable thing of a lap.

    things: {id: (class, kind, center (3,), yaw)}, kind "object", "phantom" or "person".
    """

    def __init__(self, opts: dict, seed: int, lap: int, n_frames: int, things: dict):
        self.opts = opts
        self.things = things
        self.state = {}
        self.alt = {}
        for tid, (cls, kind, _, _) in things.items():
            if opts["view_correlation"] > 0:
                rng = np.random.default_rng([seed, lap, 0x57A7E, tid])
                self.state[tid] = smooth_noise(rng, n_frames, opts["correlation_frames"], 3)
            # Seeded by the object alone: the detector mislabels the same table in every lap.
            if kind == "object" and cls in SYSTEMATIC:
                if np.random.default_rng([seed, 0x3A1E, tid]).uniform() < opts["mislabel_objects"]:
                    self.alt[tid] = SYSTEMATIC[cls]

    def frame(self, index: int, T_world_camera: np.ndarray, rng: np.random.Generator) -> FrameViews:
        return FrameViews(self, index, T_world_camera, rng)


class FrameViews:
    """The view model bound to one frame (its index, true camera pose and own random draws)."""

    def __init__(self, model: ViewModel, index: int, T_world_camera: np.ndarray, rng: np.random.Generator):
        self.model, self.index, self.T = model, index, T_world_camera
        self.opts = model.opts
        self.rng = rng

    def miss_probability(self, tid: int, p: float) -> float:
        """p (the base rule's miss probability) times the class's multiplier, plus oblique_miss
        times (1 - cos) of the angle between a facing thing's front and the camera."""
        cls, kind, center, yaw = self.model.things[tid]
        weight = CLASS_MISS.get(kind if kind != "object" else cls, 1.0)
        p = p * (1 + self.opts["class_miss"] * (weight - 1))
        if cls in FACING and self.opts["oblique_miss"] > 0:
            d = self.T[:2, 3] - center[:2]
            cos_a = float(d @ (math.cos(yaw), math.sin(yaw))) / max(1e-9, float(np.hypot(*d)))
            p += self.opts["oblique_miss"] * min(1.0, 1.0 - cos_a)
        return p

    def uniform(self, tid: int, u: float, channel: int) -> float:
        """The uniform draw u made to persist over nearby views: its normal score mixed with the
        thing's slow state (weight view_correlation) and mapped back through the normal CDF, so it
        stays uniform and the rates stay what they are; u itself when views are independent."""
        rho = self.opts["view_correlation"]
        state = self.model.state.get(tid)
        if rho == 0 or state is None:
            return u
        return float(ndtr(rho * state[self.index, channel] + math.sqrt(1 - rho * rho) * ndtri(u)))

    def systematic_label(self, tid: int) -> str | None:
        """The thing's fixed other class in this view (in a share mislabel_share of its views), or
        None."""
        alt = self.model.alt.get(tid)
        if alt is None:
            return None
        return alt if self.uniform(tid, self.rng.uniform(), MISLABEL) < self.opts["mislabel_share"] else None

    def shape_mask(self, mask: np.ndarray) -> np.ndarray:
        """The mask as a CNN would give it (cnn_masks = 1), else unchanged."""
        return cnn_mask(mask) if self.opts["cnn_masks"] else mask


def cnn_mask(mask: np.ndarray, grid: int = MASK_GRID) -> np.ndarray:
    """A mask (H, W) bool as a Mask R-CNN head gives it: its bounding box averaged onto a grid x grid
    cell map, gaps of up to 6 cells closed (a chair's back becomes solid), upright parts under 3
    cells wide opened away (thin legs go), blurred, bilinearly upsampled and cut at 0.5 (a smooth
    outline)."""
    vs, us = np.nonzero(mask)
    if vs.size == 0:
        return mask
    v0, v1, u0, u1 = vs.min(), vs.max() + 1, us.min(), us.max() + 1
    crop = mask[v0:v1, u0:u1].astype(np.float64)
    h, w = crop.shape
    # Area average onto the grid (each cell the share of its pixels in the mask); a box smaller
    # than the grid is first repeated up to it.
    rep = (max(1, -(-grid // h)), max(1, -(-grid // w)))
    big = np.repeat(np.repeat(crop, rep[0], axis=0), rep[1], axis=1)
    edges_v = np.linspace(0, big.shape[0], grid + 1).astype(int)[:-1]
    edges_u = np.linspace(0, big.shape[1], grid + 1).astype(int)[:-1]
    sums = np.add.reduceat(np.add.reduceat(big, edges_v, axis=0), edges_u, axis=1)
    counts = np.outer(np.diff(np.append(edges_v, big.shape[0])), np.diff(np.append(edges_u, big.shape[1])))
    cells = sums / counts
    # Zeros around (outside the box is background), then: close gaps up to 6 cells, open away
    # upright parts under 3 cells wide (legs; a seat's edge or a rail stays), smooth the outline.
    pad = 4
    cells = np.pad(cells, pad)
    cells = ndimage.grey_closing(cells, size=(7, 7), mode="constant")
    cells = ndimage.grey_opening(cells, size=(1, 3), mode="constant")
    cells = ndimage.gaussian_filter(cells, 0.7, mode="constant")
    # Bilinear, cell centres at pixel centres.
    rv = (np.arange(h) + 0.5) * grid / h - 0.5 + pad
    ru = (np.arange(w) + 0.5) * grid / w - 0.5 + pad
    up = ndimage.map_coordinates(cells, np.meshgrid(rv, ru, indexing="ij"), order=1, mode="nearest")
    out = np.zeros_like(mask)
    out[v0:v1, u0:u1] = up >= 0.5
    return out

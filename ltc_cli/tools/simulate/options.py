"""The simulator's vocabulary, its options with their defaults, and their validation."""

from __future__ import annotations

import math

import numpy as np

from ltc_cli.errors import ConfigError

#: The detector vocabulary written to every recording.yaml (COCO names).
CLASSES = (
    "bed",
    "couch",
    "chair",
    "dining table",
    "tv",
    "refrigerator",
    "oven",
    "sink",
    "toilet",
    "potted plant",
    "cup",
    "bowl",
    "book",
    "bottle",
    "laptop",
)

#: Classes the simulated detector confuses with each other (a real detector's typical mistakes).
CONFUSABLE = {
    "bed": ("couch",),
    "couch": ("chair", "bed"),
    "chair": ("couch",),
    "dining table": ("bed",),
    "tv": ("laptop",),
    "refrigerator": ("oven",),
    "oven": ("refrigerator",),
    "sink": ("toilet",),
    "toilet": ("sink",),
    "potted plant": ("bottle",),
    "cup": ("bowl", "bottle"),
    "bowl": ("cup",),
    "book": ("laptop",),
    "bottle": ("cup",),
    "laptop": ("book", "tv"),
}

SCENES = ("tiny", "small", "medium", "large")

#: Frames of the loop in each room, per scene (option frames_per_room overrides it).
FRAMES_PER_ROOM = {"tiny": 12, "small": 36, "medium": 36, "large": 36}

#: Options of :func:`ltc_cli.tools.simulate.simulate` and their defaults.
DEFAULTS = {
    # Depth sensor (structured light / stereo, Kinect-like): noise std in metres at 1 m, growing
    # with depth squared; spatially correlated over noise_block x noise_block pixels (the sensor
    # matches ~9x9 pixel windows, so neighbours share their errors; this also keeps the PNGs
    # compressible). Depth is quantised in disparity: the step is depth_resolution at 1 m and grows
    # with depth squared (0: millimetres only).
    "depth_noise": 0.005,
    "depth_resolution": 0.003,
    "noise_block": 8,
    "min_range": 0.3,  # no reading nearer than this (m)
    "max_range": 8.0,  # no reading farther than this (m)
    "rgb_noise": 2.0,  # std of the colour noise in 8-bit levels (also in blocks)
    # Detector.
    "miss_rate": 0.15,
    "confusion_rate": 0.05,
    "bleed_px": 3,
    "false_positive_rate": 0.05,  # per frame
    "split_rate": 0.03,  # a mask split in two (over-segmentation)
    "min_pixels": None,  # fewer visible pixels: never detected; default 5e-4 of the image, >= 20
    # Changes between laps, as fractions of the objects of the previous lap (at least one each
    # when the fraction is above 0).
    "moved_fraction": 0.15,
    "removed_fraction": 0.1,
    "added_fraction": 0.1,
    # Robot path.
    "frames_per_room": None,  # frames of the loop in each room; default per scene
    "transit_step": 0.8,  # metres between frames when going from room to room
    "camera_height": 1.0,
    "camera_pitch_deg": 12.0,
}

_UNIT = ("miss_rate", "confusion_rate", "false_positive_rate", "split_rate",
         "moved_fraction", "removed_fraction", "added_fraction")
_NON_NEGATIVE = ("depth_noise", "depth_resolution", "rgb_noise", "bleed_px", "min_range")
_POSITIVE = ("noise_block", "transit_step", "camera_height", "max_range")


def check_options(options: dict) -> dict:
    """The full option dict (defaults filled in) from the user's, checked; ConfigError naming the
    option otherwise."""
    unknown = sorted(set(options) - set(DEFAULTS))
    if unknown:
        raise ConfigError(f"unknown simulate option(s): {', '.join(unknown)} (known: {', '.join(DEFAULTS)})")
    opts = dict(DEFAULTS)
    for key, value in options.items():
        if value is None:
            opts[key] = None
            continue
        try:
            v = float(value)
        except (TypeError, ValueError):
            raise ConfigError(f"simulate option {key}: not a number: {value!r}") from None
        if not math.isfinite(v):
            raise ConfigError(f"simulate option {key}: not a finite number: {value!r}")
        opts[key] = v
    for key in _UNIT:
        if not 0.0 <= opts[key] <= 1.0:
            raise ConfigError(f"simulate option {key} must be within [0, 1], not {opts[key]}")
    for key in _NON_NEGATIVE:
        if opts[key] < 0:
            raise ConfigError(f"simulate option {key} must be >= 0, not {opts[key]}")
    for key in _POSITIVE:
        if not opts[key] > 0:
            raise ConfigError(f"simulate option {key} must be > 0, not {opts[key]}")
    if opts["max_range"] <= opts["min_range"]:
        raise ConfigError("simulate option max_range must be above min_range")
    if not -60 <= opts["camera_pitch_deg"] <= 60:
        raise ConfigError("simulate option camera_pitch_deg must be within [-60, 60]")
    if not 0.2 <= opts["camera_height"] <= 2.2:
        raise ConfigError("simulate option camera_height must be within [0.2, 2.2] m (under the ceiling)")
    if opts["frames_per_room"] is not None:
        if opts["frames_per_room"] != int(opts["frames_per_room"]) or not 1 <= opts["frames_per_room"] <= 1000:
            raise ConfigError("simulate option frames_per_room must be an integer in [1, 1000]")
        opts["frames_per_room"] = int(opts["frames_per_room"])
    if opts["min_pixels"] is not None:
        if opts["min_pixels"] < 1:
            raise ConfigError("simulate option min_pixels must be >= 1")
        opts["min_pixels"] = int(opts["min_pixels"])
    opts["bleed_px"] = int(round(opts["bleed_px"]))
    opts["noise_block"] = int(round(opts["noise_block"]))
    return opts


def check_int(name, value, lo, hi) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not lo <= value <= hi:
        raise ConfigError(f"simulate: {name} must be an integer in [{lo}, {hi}], not {value!r}")
    return int(value)

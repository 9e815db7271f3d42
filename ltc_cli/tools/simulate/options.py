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

#: Options of :func:`ltc_cli.tools.simulate.simulate` and their defaults: the ``benign`` profile.
BASE_DEFAULTS = {
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
    "bleed_px": 3,  # at 640 x 480; scaled up with a larger image's longer side
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

#: The real failure modes (issue 9), all off by default; the ``realistic`` profile turns them on.
#: Each is an option of its own (docs/simulator.md).
REALISM_DEFAULTS = {
    # Localisation: poses.txt holds the true pose moved by a slowly varying error (a Gaussian
    # process along the path, correlation drift_frames frames, clipped at 2.5 std; z and the tilts
    # get a quarter and a third of it) plus per-frame jitter; the images are rendered from the true
    # pose, as a real localiser's estimate differs from where the camera really was.
    "pose_drift_m": 0.0,
    "pose_drift_deg": 0.0,
    "pose_jitter_m": 0.0,
    "pose_jitter_deg": 0.0,
    "drift_frames": 15.0,
    # Detector: per-class miss rates (weight of the table CLASS_MISS: 0 = one rate for every
    # class), an extra miss probability for flat-faced classes seen at an angle (tv, sink,
    # laptop), misses and mislabels correlated over correlation_frames nearby views of one object
    # (view_correlation 0 = independent per frame), systematic mislabels (a share of objects
    # labelled as one fixed other class in a share of their views), recurring phantoms (a poster
    # seen as a tv, clutter on a table seen as a book) and CNN-like masks (on a 28 x 28 grid:
    # gaps filled, thin legs dropped, outline smoothed; 0 or 1).
    "class_miss": 0.0,
    "oblique_miss": 0.0,
    "view_correlation": 0.0,
    "correlation_frames": 6.0,
    "mislabel_objects": 0.0,
    "mislabel_share": 0.0,
    "phantoms_per_room": 0.0,
    "cnn_masks": 0.0,
    # Depth: no reading on dark and on shiny surfaces with these probabilities (in blobs), and
    # flying pixels: this share of the pixels on a depth edge mixes foreground and background.
    "dark_dropout": 0.0,
    "shiny_dropout": 0.0,
    "flying_pixels": 0.0,
    # Scene: each furniture item scaled by up to +-size_variation along each axis (a fridge is not
    # always 0.75 m deep); people walking through (class person, never in the ground truth).
    "size_variation": 0.0,
    "people_per_room": 0.0,
}

DEFAULTS = {**BASE_DEFAULTS, **REALISM_DEFAULTS}

#: Option values of each profile over DEFAULTS. ``benign`` is the simulator as it was before
#: issue 9 (byte-identical output); ``realistic`` is the accuracy benchmark's default.
PROFILES = {
    "benign": {},
    "realistic": {
        "pose_drift_m": 0.04,
        "pose_drift_deg": 1.5,
        "pose_jitter_m": 0.005,
        "pose_jitter_deg": 0.2,
        "class_miss": 1.0,
        "oblique_miss": 0.5,
        "view_correlation": 0.85,
        "mislabel_objects": 0.25,
        "mislabel_share": 0.35,
        "phantoms_per_room": 1.0,
        "cnn_masks": 1.0,
        "dark_dropout": 0.5,
        "shiny_dropout": 0.25,
        "flying_pixels": 0.5,
        "size_variation": 0.12,
        "people_per_room": 1.0,
    },
}

_UNIT = ("miss_rate", "confusion_rate", "false_positive_rate", "split_rate",
         "moved_fraction", "removed_fraction", "added_fraction", "class_miss", "oblique_miss",
         "view_correlation", "mislabel_objects", "mislabel_share", "dark_dropout", "shiny_dropout",
         "flying_pixels")
_NON_NEGATIVE = ("depth_noise", "depth_resolution", "rgb_noise", "bleed_px", "min_range", "pose_drift_m",
                 "pose_drift_deg", "pose_jitter_m", "pose_jitter_deg")
_POSITIVE = ("noise_block", "transit_step", "camera_height", "max_range")
_AT_LEAST_ONE = ("drift_frames", "correlation_frames")
_BOUNDED = {"size_variation": 0.5, "phantoms_per_room": 5, "people_per_room": 5}


def check_options(options: dict, profile: str = "benign") -> dict:
    """The full option dict (the profile's values over the defaults, then the user's), checked;
    ConfigError naming the option otherwise."""
    if profile not in PROFILES:
        raise ConfigError(f"simulate: unknown profile {profile!r} (choose from {', '.join(PROFILES)})")
    unknown = sorted(set(options) - set(DEFAULTS))
    if unknown:
        raise ConfigError(f"unknown simulate option(s): {', '.join(unknown)} (known: {', '.join(DEFAULTS)})")
    opts = {**DEFAULTS, **PROFILES[profile]}
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
    for key in _AT_LEAST_ONE:
        if not opts[key] >= 1:
            raise ConfigError(f"simulate option {key} must be >= 1, not {opts[key]}")
    for key, hi in _BOUNDED.items():
        if not 0 <= opts[key] <= hi:
            raise ConfigError(f"simulate option {key} must be within [0, {hi}], not {opts[key]}")
    if opts["cnn_masks"] not in (0, 1):
        raise ConfigError(f"simulate option cnn_masks must be 0 or 1, not {opts['cnn_masks']}")
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


def recorded_options(opts: dict) -> dict:
    """The options written to recording.yaml: every base option, and the realism options when any
    of them is on (so a benign recording's file is what it was before they existed)."""
    on = any(opts[k] != v for k, v in REALISM_DEFAULTS.items())
    return {k: v for k, v in opts.items() if k in BASE_DEFAULTS or on}


def check_int(name, value, lo, hi) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not lo <= value <= hi:
        raise ConfigError(f"simulate: {name} must be an integer in [{lo}, {hi}], not {value!r}")
    return int(value)

"""What the readers share: their options (JSON Schema), intrinsics, up axis, pose files, identity
hashes, and the one frame loader every layout's frames go through.

A reader lists its frames as :class:`FrameSource` (key, image paths, a pose callable) and turns them
into lazy :class:`~ltc_cli.types.FrameRef` with :func:`frame_refs`; each frame's ``load()`` then
reads the pose first (cheap, and the usual failure), then depth, then colour, and raises
:class:`~ltc_cli.errors.FrameError` naming the file at fault, so a bad frame is skipped and counted
instead of ending the ingest.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field, replace
from functools import partial
from pathlib import Path
from typing import Callable, Iterable

import numpy as np
from PIL import Image

from ltc_cli.errors import ConfigError, FrameError, RecordingError
from ltc_cli.geometry.camera import is_rotation, pose_matrix
from ltc_cli.recordings.images import check_rgb, load_depth, load_rgb
from ltc_cli.types import Frame, FrameRef, Intrinsics
from ltc_cli.validation import check_options

# A quaternion further than this from unit norm is a corrupt pose, not rounding in a text file.
QUAT_NORM_RANGE = (0.99, 1.01)
# Rotation matrices in text files carry 6-7 significant digits; 1e-2 accepts that and still rejects
# scaled or sheared matrices. Accepted ones are re-orthonormalised.
ROTATION_TOL = 1e-2

AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}

_POSITIVE = {"type": "number", "exclusiveMinimum": 0}
# Options every reader of an existing layout takes (DESIGN.md section 3; plugins/readers/__init__.py).
COMMON_OPTIONS = {
    "depth_scale": {**_POSITIVE, "description": "metres = stored depth value / depth_scale"},
    "intrinsics": {
        "description": "{fx, fy, cx, cy}, [fx, fy, cx, cy] or \"fx,fy,cx,cy\" in pixels, with positive fx, fy (overrides the layout's camera)",
        "oneOf": [
            {
                "type": "object",
                "required": ["fx", "fy", "cx", "cy"],
                "additionalProperties": False,
                "properties": {"fx": _POSITIVE, "fy": _POSITIVE, "cx": {"type": "number"},
                               "cy": {"type": "number"}},
            },
            {"type": "array", "prefixItems": [_POSITIVE, _POSITIVE, {"type": "number"}, {"type": "number"}],
             "minItems": 4, "maxItems": 4},
            # "FX,FY,CX,CY" as typed on a command line (-r intrinsics=518,519,325.5,253.5).
            {"type": "string", "pattern": r"^\s*\+?[0-9.eE+-]+(\s*,\s*[+-]?[0-9.eE+-]+){3}\s*$"},
        ],
    },
    "up": {
        "description": "'estimate', null (already z-up), an axis like '-y' or a non-zero 3-vector (the world's up)",
        "anyOf": [
            {"type": "null"},
            {"const": "estimate"},
            {"type": "string", "pattern": r"^\s*[+-]?[xyzXYZ]\s*$"},
            {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3,
             "not": {"items": {"const": 0}}},
        ],
    },
}  # fmt: skip


#: The class list of a layout that has no file for it (what recording.yaml's ``classes`` says).
CLASSES_OPTION = {"type": "array", "items": {"type": "string", "minLength": 1}, "uniqueItems": True,
                  "description": "the recording's class list, e.g. [chair, couch, dining table]"}


def options_schema(depth_scale: float, up, **extra: dict) -> dict:
    """The options schema of a reader: the common options with this layout's defaults, and its own."""
    props = {
        **COMMON_OPTIONS,
        "depth_scale": {**COMMON_OPTIONS["depth_scale"], "default": depth_scale},
        "up": {**COMMON_OPTIONS["up"], "default": up},
        **extra,
    }
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", "type": "object",
            "additionalProperties": False, "properties": props}  # fmt: skip


def open_folder(path, options, schema: dict, reader: str) -> tuple[Path, dict]:
    """(folder, options checked against ``schema`` with its defaults) of a recording to open."""
    folder = Path(path)
    opts = check_options(options, schema, f"reader {reader!r}")
    if not folder.is_dir():
        raise RecordingError("recording folder does not exist", folder)
    return folder, opts


def up_direction(value):
    """An ``up`` value -> None (already z-up), "estimate", or the unit direction as a 3-tuple.

    Accepts an axis name (``"-y"``, ``"+z"``, ``"x"``) or a 3-vector; raises ValueError for a zero
    or non-finite vector.
    """
    if value is None or value == "estimate":
        return value
    if isinstance(value, str):
        name = value.strip().lower()
        sign = -1.0 if name.startswith("-") else 1.0
        vec = sign * np.array(AXES[name.lstrip("+-")])
    else:
        vec = np.asarray(value, dtype=np.float64)
    norm = float(np.linalg.norm(vec))
    if vec.shape != (3,) or not np.isfinite(norm) or norm < 1e-9:
        raise ValueError(f"up must be a non-zero 3-vector, got {value!r}")
    vec = vec / norm
    return None if np.allclose(vec, [0.0, 0.0, 1.0]) else tuple(float(v) for v in vec)


def up_option(opts: dict, reader: str):
    try:
        return up_direction(opts["up"])
    except ValueError as exc:
        raise ConfigError(f"reader {reader!r}: option 'up': {exc}") from None


def intrinsics_option(opts: dict) -> tuple[float, float, float, float] | None:
    """The (schema-checked) ``intrinsics`` override as (fx, fy, cx, cy), or None when not given."""
    value = opts.get("intrinsics")
    if value is None:
        return None
    if isinstance(value, dict):
        value = [value[k] for k in ("fx", "fy", "cx", "cy")]
    elif isinstance(value, str):
        try:
            value = [float(v) for v in value.split(",")]
        except ValueError:
            raise ConfigError(f"option 'intrinsics' must be FX,FY,CX,CY numbers, got {value!r}") from None
    vals = tuple(float(v) for v in value)
    if not (all(np.isfinite(vals)) and vals[0] > 0 and vals[1] > 0):
        raise ConfigError(f"option 'intrinsics' needs finite numbers and positive FX, FY, got {value!r}")
    return vals


def make_intrinsics(width, height, fx_fy_cx_cy, override) -> Intrinsics:
    fx, fy, cx, cy = override if override is not None else fx_fy_cx_cy
    return Intrinsics(int(width), int(height), float(fx), float(fy), float(cx), float(cy))


def identity(files: Iterable[tuple[str, bytes]]) -> str:
    """sha256 (first 16 hex digits) of (relative name, bytes) pairs: location-independent."""
    h = hashlib.sha256()
    for name, data in files:
        name_b = name.encode("utf-8")
        # Length prefixes: no two different file lists hash the same byte stream.
        h.update(len(name_b).to_bytes(8, "little") + name_b)
        h.update(len(data).to_bytes(8, "little") + data)
    return h.hexdigest()[:16]


def read_bytes(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except OSError as exc:
        raise RecordingError(f"cannot read file ({exc.strerror or exc})", path) from None


def image_size(path: Path) -> tuple[int, int]:
    """(width, height) from an image header, without decoding the pixels."""
    try:
        with Image.open(path) as img:
            return img.size
    except (OSError, ValueError, SyntaxError) as exc:
        raise RecordingError(
            f"cannot read image to find the camera's size ({exc.__class__.__name__}: {exc})", path
        ) from None


def first_size(paths: Iterable[Path], folder: Path) -> tuple[int, int]:
    """The image size of the first existing file among ``paths`` (the camera's resolution)."""
    for p in paths:
        if p.is_file():
            return image_size(p)
    raise RecordingError("no depth image of any frame exists", folder)


def first_existing(*candidates: Path) -> Path:
    """The first of ``candidates`` that is a file, else the first (its load() names it missing)."""
    return next((p for p in candidates if p.is_file()), candidates[0])


def quaternion_pose(values, path, where: str = "") -> np.ndarray:
    """``tx ty tz qx qy qz qw`` (7,) -> T (4, 4); FrameError naming the file (and ``where`` in it,
    e.g. "line 3") when it is not a pose."""
    vals = np.asarray(values, dtype=np.float64)
    at = f"{where}: " if where else ""
    if not np.all(np.isfinite(vals)):
        raise FrameError(f"{at}pose has non-finite values", path)
    norm = float(np.linalg.norm(vals[3:]))
    # A quaternion far from unit length is not a rotation written with rounding: refuse it rather
    # than guess.
    if not QUAT_NORM_RANGE[0] <= norm <= QUAT_NORM_RANGE[1]:
        raise FrameError(f"{at}pose quaternion has norm {norm:.4g}, not 1: not a rotation", path)
    return pose_matrix(vals[:3], vals[3:] / norm)


def checked_matrix_pose(T: np.ndarray, path: Path) -> np.ndarray:
    """Validate a 4x4 camera-to-world pose; returns it with its rotation re-orthonormalised."""
    if T.shape != (4, 4):
        raise FrameError(f"pose must be a 4x4 matrix, got {T.size} numbers", path)
    if not np.all(np.isfinite(T)):
        # ScanNet writes -inf poses for frames its tracker lost.
        raise FrameError("pose has non-finite values (frame without a valid pose)", path)
    if np.abs(T[3] - [0.0, 0.0, 0.0, 1.0]).max() > 1e-3:
        raise FrameError(f"pose's last row must be 0 0 0 1, got {T[3].tolist()}", path)
    R = T[:3, :3]
    if not is_rotation(R, tol=ROTATION_TOL):
        raise FrameError("pose's 3x3 part is not a rotation matrix", path)
    U, _, Vt = np.linalg.svd(R)
    out = np.array(T, dtype=np.float64)
    out[:3, :3] = U @ Vt
    out[3] = [0.0, 0.0, 0.0, 1.0]
    return out


def read_matrix_pose(path: Path) -> np.ndarray:
    """Read a text file holding a 4x4 matrix (16 numbers, any whitespace); raises FrameError."""
    if not path.is_file():
        raise FrameError("pose file is missing", path)
    try:
        tokens = path.read_text(encoding="utf-8-sig", errors="replace").split()
        values = np.array([float(t) for t in tokens], dtype=np.float64)
    except (OSError, ValueError) as exc:
        raise FrameError(f"cannot read pose as numbers ({exc})", path) from None
    if values.size != 16:
        raise FrameError(f"pose must be a 4x4 matrix, got {values.size} numbers", path)
    return checked_matrix_pose(values.reshape(4, 4), path)


def read_matrix_file(path: Path, what: str) -> np.ndarray:
    """An intrinsics matrix file (3x3 or 4x4) as numbers; raises RecordingError."""
    try:
        values = np.array([float(t) for t in path.read_text(encoding="utf-8-sig").split()])
    except (OSError, ValueError) as exc:
        raise RecordingError(f"cannot read {what} as numbers ({exc})", path) from None
    if values.size not in (9, 16) or not np.all(np.isfinite(values)):
        raise RecordingError(f"{what} must be a 3x3 or 4x4 matrix of finite numbers", path)
    n = 3 if values.size == 9 else 4
    K = values.reshape(n, n)
    if K[0, 0] <= 0 or K[1, 1] <= 0:
        raise RecordingError(f"{what} has non-positive focal lengths", path)
    return K


# --------------------------------------------------------------------------------------------------
# Associating stamps


def nearest_index(sorted_stamps: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Index of the nearest of ``sorted_stamps`` (M,) for each of ``t`` (N,)."""
    i = np.clip(np.searchsorted(sorted_stamps, t), 1, len(sorted_stamps) - 1)
    left, right = sorted_stamps[i - 1], sorted_stamps[i]
    return np.where(np.abs(t - left) <= np.abs(right - t), i - 1, i)


def associate_nearest(rgb_t: np.ndarray, depth_t: np.ndarray, max_dt: float) -> tuple[list[int], np.ndarray]:
    """(rgb indices with a depth image within ``max_dt``, sorted; depth index (N,) of every rgb).

    Nearest depth stamp per rgb stamp; each depth image is used once, by the closest rgb stamp
    (TUM's associate.py rule; the bag reader pairs colour and depth messages the same way).
    """
    d_order = np.argsort(depth_t, kind="stable")
    depth_sorted = depth_t[d_order]
    if len(depth_sorted) == 1:
        nearest_d = np.zeros(len(rgb_t), dtype=int)
    else:
        nearest_d = nearest_index(depth_sorted, rgb_t)
    d_idx = d_order[nearest_d]
    d_diff = np.abs(depth_t[d_idx] - rgb_t)
    best_for_depth: dict[int, int] = {}
    for i in np.flatnonzero(d_diff <= max_dt):
        j = int(d_idx[i])
        if j not in best_for_depth or d_diff[i] < d_diff[best_for_depth[j]]:
            best_for_depth[j] = int(i)
    return sorted(best_for_depth.values()), d_idx


# --------------------------------------------------------------------------------------------------
# The frame loader


@dataclass(frozen=True)
class ImageFormat:
    """How a recording stores its images.

    resize_rgb: colour images of another size are resized to the camera's (ScanNet's colour camera
        is not its depth camera); otherwise a colour image of another size is a FrameError.
    invalid_raw: a stored depth value meaning "no reading" besides 0 (7-Scenes: 65535).
    """

    intrinsics: Intrinsics
    depth_scale: float
    resize_rgb: bool = False
    invalid_raw: int | None = None


@dataclass(frozen=True)
class FrameSource:
    """Where one frame's pieces are: ``pose()`` returns T_world_camera (4, 4) or raises FrameError."""

    key: str
    rgb_path: Path
    depth_path: Path
    pose: Callable[[], np.ndarray]
    extra: dict = field(default_factory=dict)


def load_frame(src: FrameSource, index: int, fmt: ImageFormat) -> Frame:
    """Read and check one frame: pose first (cheap, the usual failure), then depth, then colour."""
    intr = fmt.intrinsics
    T_world_camera = src.pose()
    depth_m = load_depth(src.depth_path, fmt.depth_scale, intr.width, intr.height, invalid_raw=fmt.invalid_raw)
    # The colour image's header is checked now (a missing or wrong image skips the frame whatever
    # the detector); its pixels are decoded when a detector first reads frame.rgb.
    if fmt.resize_rgb:
        check_rgb(src.rgb_path)

        def rgb_loader() -> np.ndarray:
            rgb = load_rgb(src.rgb_path)
            if rgb.shape[:2] != (intr.height, intr.width):
                rgb = np.asarray(Image.fromarray(rgb).resize((intr.width, intr.height), Image.BILINEAR))
            return rgb
    else:
        check_rgb(src.rgb_path, intr.width, intr.height)

        def rgb_loader() -> np.ndarray:
            return load_rgb(src.rgb_path, intr.width, intr.height)
    return Frame(
        key=src.key,
        index=index,
        depth_m=depth_m,
        T_world_camera=T_world_camera,
        intrinsics=intr,
        rgb_loader=rgb_loader,
        rgb_path=str(src.rgb_path),
        depth_path=str(src.depth_path),
        extra=dict(src.extra),
    )


class _PoseOnce:
    """A frame's ``pose()``, read once: the ingest asks for it before loading (a still camera's
    frames, ingest/keyframes.py), the look-ahead too, and the load again; a TUM pose is a slerp
    (about 1 ms). An error is not kept: it is raised again at the next call."""

    def __init__(self, pose: Callable[[], np.ndarray]):
        self.pose, self.T = pose, None

    def __call__(self) -> np.ndarray:
        if self.T is None:
            self.T = self.pose()
        return self.T.copy()


def frame_refs(sources: Iterable[FrameSource], fmt: ImageFormat) -> list[FrameRef]:
    """The recording's frames, in order, each loaded lazily by :func:`load_frame`."""
    refs = []
    for index, src in enumerate(sources):
        pose = _PoseOnce(src.pose)
        src = replace(src, pose=pose)
        refs.append(FrameRef(key=src.key, index=index, load=partial(load_frame, src, index, fmt), pose=pose))
    return refs

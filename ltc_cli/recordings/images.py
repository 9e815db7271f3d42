"""Reading and checking RGB and depth images (Pillow). Readers share these so every layout gives
the same clear errors: each names the file and what is wrong with it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image, UnidentifiedImageError

from ltc_cli.errors import FrameError


def _open(path: Path) -> Image.Image:
    if not path.is_file():
        raise FrameError("image file is missing", path)
    try:
        img = Image.open(path)
        img.load()
        return img
    except (UnidentifiedImageError, OSError, ValueError, SyntaxError) as exc:
        raise FrameError(f"cannot read image ({exc.__class__.__name__}: {exc})", path) from None


def load_rgb(path, width: int | None = None, height: int | None = None) -> np.ndarray:
    """RGB image (H, W, 3) uint8; checks the size against the camera's when given."""
    path = Path(path)
    img = _open(path)
    if img.mode in ("I;16", "I;16B", "I;16L", "I", "F"):
        # A 16-bit (or wider) single-channel image is a depth image given as colour: converting it
        # would clip every value to white and the detector would see nothing.
        raise FrameError(f"colour image is a 16-bit single-channel image (mode {img.mode}), not 8-bit "
                         "colour: is it a depth image?", path)
    if img.mode != "RGB":
        img = img.convert("RGB")
    arr = np.asarray(img)
    if width is not None and (arr.shape[1], arr.shape[0]) != (width, height):
        raise FrameError(
            f"colour image is {arr.shape[1]}x{arr.shape[0]}, the camera is {width}x{height}", path
        )
    return arr


def load_depth(
    path, scale: float, width: int | None = None, height: int | None = None, invalid_raw: int | None = None
) -> np.ndarray:
    """Depth image as (H, W) float32 metres (value / scale; 0 = no reading).

    Only 16-bit single-channel images are accepted: an 8-bit or colour "depth" image is almost always
    the wrong file, and silently scaling it would build a wrong map. ``invalid_raw`` is a stored
    value that also means "no reading" (7-Scenes: 65535). An image without any reading is refused:
    a frame that sees nothing would count every object in view as missed.
    """
    path = Path(path)
    img = _open(path)
    arr = np.asarray(img)
    if img.mode in ("I;16", "I;16B", "I;16L") or arr.dtype == np.uint16:
        raw = arr.astype(np.uint16, copy=False)
    elif img.mode == "I" and arr.ndim == 2:
        # Pillow widens some 16-bit PNG/PGM files to 32-bit; values must still fit in 16 bits.
        if arr.size and (arr.min() < 0 or arr.max() > 65535):
            raise FrameError("depth image has values outside 0..65535; expected 16-bit depth", path)
        raw = arr.astype(np.uint16)
    else:
        raise FrameError(
            f"depth image must be 16-bit single-channel, got mode {img.mode} ({arr.dtype})", path
        )
    if raw.ndim != 2:
        raise FrameError(f"depth image must have one channel, got shape {raw.shape}", path)
    if width is not None and (raw.shape[1], raw.shape[0]) != (width, height):
        raise FrameError(
            f"depth image is {raw.shape[1]}x{raw.shape[0]}, the camera is {width}x{height}", path
        )
    if invalid_raw is not None:
        raw = np.where(raw == invalid_raw, 0, raw)
    if not raw.any():
        raise FrameError("depth image has no readings (every pixel is 0)", path)
    return raw.astype(np.float32) / np.float32(scale)

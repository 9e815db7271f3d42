"""ROS image messages -> numpy: ``sensor_msgs/Image`` (colour and depth encodings),
``sensor_msgs/CompressedImage`` (JPEG / PNG colour) and the ``compressedDepth`` transport.

Pure functions over the deserialised messages (duck-typed: ``encoding``, ``height``, ``width``,
``step``, ``is_bigendian``, ``data``; ``format`` and ``data`` for compressed ones), so they need no
ROS. Each raises ValueError with what is wrong; the reader turns it into a FrameError naming the bag,
the topic and the stamp. Depth follows REP 118: ``16UC1`` in millimetres (``depth_scale`` 1000),
``32FC1`` in metres; NaN, infinite and non-positive readings become 0 (no reading).
"""

from __future__ import annotations

import io
import struct

import numpy as np
from PIL import Image, UnidentifiedImageError

#: Encodings of colour images and how to get RGB from them (channel order, channels kept).
COLOR_ENCODINGS = {
    "rgb8": ((0, 1, 2), 3), "rgba8": ((0, 1, 2), 4), "bgr8": ((2, 1, 0), 3), "bgra8": ((2, 1, 0), 4),
    "8UC3": ((2, 1, 0), 3),  # OpenCV's default order
    "mono8": ((0, 0, 0), 1), "8UC1": ((0, 0, 0), 1),
}  # fmt: skip
DEPTH_ENCODINGS = ("16UC1", "mono16", "32FC1")
# compressed_depth_image_transport writes a 12-byte header (int32 format, float32 depthQuantA, B)
# before the PNG.
_DEPTH_HEADER = struct.Struct("<iff")
_PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def is_compressed_depth(fmt: str) -> bool:
    """A CompressedImage format of depth: the compressedDepth transport, or a 16-bit PNG of raw
    depth ("16UC1; png compressed")."""
    return "compresseddepth" in fmt.replace(" ", "").lower() or fmt.split(";")[0].strip() in ("16UC1", "mono16")


def _pixels(msg, dtype: np.dtype, channels: int) -> np.ndarray:
    """The (H, W[, C]) array of a raw Image, honouring ``step`` (row padding) and byte order."""
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    item = np.dtype(dtype).itemsize * channels
    data = np.frombuffer(memoryview(msg.data).cast("B"), dtype=np.uint8)
    if h <= 0 or w <= 0 or step < w * item or data.size < step * (h - 1) + w * item:
        raise ValueError(f"{w}x{h} image with step {step} does not fit its {data.size} bytes")
    rows = np.lib.stride_tricks.as_strided(data, (h, w * item), (step, 1))
    dt = np.dtype(dtype).newbyteorder(">" if msg.is_bigendian else "<")
    arr = np.ascontiguousarray(rows).view(dt).reshape((h, w, channels) if channels > 1 else (h, w))
    return arr.astype(np.dtype(dtype).newbyteorder("="), copy=False)


def image_rgb(msg) -> np.ndarray:
    """A raw colour Image -> (H, W, 3) uint8 RGB."""
    enc = str(msg.encoding)
    if enc not in COLOR_ENCODINGS:
        raise ValueError(f"colour encoding {enc!r} is not supported ({', '.join(COLOR_ENCODINGS)})")
    order, channels = COLOR_ENCODINGS[enc]
    arr = _pixels(msg, np.uint8, channels)
    if channels == 1:
        arr = arr[..., None]
    return np.ascontiguousarray(arr[..., list(order)])


def compressed_rgb(msg) -> np.ndarray:
    """A CompressedImage (JPEG, PNG, ...) -> (H, W, 3) uint8 RGB."""
    try:
        with Image.open(io.BytesIO(bytes(msg.data))) as img:
            return np.asarray(img.convert("RGB"))
    except (UnidentifiedImageError, OSError, ValueError) as exc:
        raise ValueError(f"cannot decode compressed image of format {msg.format!r} ({exc})") from None


def _depth_metres(raw: np.ndarray, scale: float) -> np.ndarray:
    """uint16 raw -> float32 metres, computed as the image readers do (so maps agree exactly)."""
    return raw.astype(np.float32) / np.float32(scale)


def _clean(depth_m: np.ndarray) -> np.ndarray:
    depth_m = np.asarray(depth_m, dtype=np.float32)
    return np.where(np.isfinite(depth_m) & (depth_m > 0), depth_m, np.float32(0.0))


def image_depth(msg, depth_scale: float) -> np.ndarray:
    """A raw depth Image -> (H, W) float32 metres (0 = no reading)."""
    enc = str(msg.encoding)
    if enc in ("16UC1", "mono16"):
        return _depth_metres(_pixels(msg, np.uint16, 1), depth_scale)
    if enc == "32FC1":
        return _clean(_pixels(msg, np.float32, 1))
    raise ValueError(f"depth encoding {enc!r} is not supported ({', '.join(DEPTH_ENCODINGS)})")


def compressed_depth(msg, depth_scale: float) -> np.ndarray:
    """A ``compressedDepth`` CompressedImage -> (H, W) float32 metres.

    ``16UC1; compressedDepth png``: the PNG holds the raw values. ``32FC1; compressedDepth png``:
    it holds quantised inverse depth, metres = A / (value - B) with the header's A and B, 0 = none.
    """
    fmt = str(msg.format)
    if "rvl" in fmt.lower():
        raise ValueError(f"compressedDepth format {fmt!r} (RVL) is not supported: record png or raw depth")
    data = bytes(msg.data)
    start = data.find(_PNG_MAGIC, 0, _DEPTH_HEADER.size + len(_PNG_MAGIC))
    if start < 0:
        raise ValueError(f"compressedDepth message of format {fmt!r} holds no PNG")
    try:
        with Image.open(io.BytesIO(data[start:])) as img:
            raw = np.asarray(img)
    except (UnidentifiedImageError, OSError, ValueError) as exc:
        raise ValueError(f"cannot decode the compressedDepth PNG ({exc})") from None
    if raw.ndim != 2:
        raise ValueError(f"compressedDepth PNG has shape {raw.shape}, not one channel")
    if fmt.split(";")[0].strip() == "32FC1":
        if start < _DEPTH_HEADER.size:
            raise ValueError("32FC1 compressedDepth message has no quantisation header")
        _, quant_a, quant_b = _DEPTH_HEADER.unpack_from(data, start - _DEPTH_HEADER.size)
        inv = raw.astype(np.float64)
        with np.errstate(divide="ignore", invalid="ignore"):
            depth = np.where(inv > 0, quant_a / (inv - quant_b), 0.0)
        return _clean(depth)
    return _depth_metres(raw.astype(np.uint16), depth_scale)

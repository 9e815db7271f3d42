"""Pillow's BILINEAR resize, bit for bit, at a fraction of its cost where it is simple (issue 11).

The YOLO letterbox scales the colour image with Pillow's ``Image.resize(..., BILINEAR)``, an
antialiasing triangle filter as wide as the scale factor. Halving (a 640x480 camera into a
320-pixel model, 1280x720 into 640) is the common case, and there the filter is fixed:

- Pillow's coefficients for output pixel i (centre 2i + 1 in input pixels, support 2) are the
  triangle's values at input pixels 2i - 1 .. 2i + 2: 1/4, 3/4, 3/4, 1/4, normalised to
  1/8, 3/8, 3/8, 1/8. In its fixed point (22 fraction bits, + 2^21 to round) that is exactly
  ``(a + 3 b + 3 c + d + 4) >> 3``, an integer formula;
- at the first and last output pixel a tap falls outside the image and Pillow renormalises the
  other three (3/7, 3/7, 1/7): those two rows or columns are computed with Pillow's own rounded
  fixed-point coefficients (:func:`edge_coefficients`);
- columns are done first, rounded to uint8, then rows, as Pillow does.

OpenCV computes the 4-tap integer sums (``filter2D``, exact in int16) and keeps every other one
(``INTER_NEAREST`` at scale 2 takes source pixel 2i); numpy does the rounding shift. 0.6 ms
instead of 1.6 ms for a 640x480 image here; tests/test_onnx_resize.py checks equality with Pillow
on random and real images. Any other size goes through Pillow itself.
"""

from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np
from PIL import Image

PRECISION_BITS = 22  # Pillow's fixed point for 8-bit images (32 - 8 - 2)
TAPS = np.array([[1, 3, 3, 1]], np.float32)  # the interior coefficients times 8


@lru_cache(maxsize=16)
def edge_coefficients(n: int) -> tuple[tuple[int, tuple[int, ...]], ...]:
    """Pillow's (first input pixel, fixed-point coefficients) of the first and the last output
    pixel when n input pixels are halved, computed as its ``precompute_coeffs`` and
    ``normalize_coeffs_8bpc`` do (scale 2, bilinear support 1 widened to 2)."""
    out = []
    for i in (0, n // 2 - 1):
        centre = (i + 0.5) * 2.0
        xmin = max(int(centre - 2.0 + 0.5), 0)
        xmax = min(int(centre + 2.0 + 0.5), n)
        w = [max(0.0, 1.0 - abs((x + xmin - centre + 0.5) * 0.5)) for x in range(xmax - xmin)]
        total = sum(w)
        out.append((xmin, tuple(int(0.5 + v / total * (1 << PRECISION_BITS)) for v in w)))
    return tuple(out)


def halve_axis(img: np.ndarray, axis: int) -> np.ndarray:
    """(H, W, C) uint8 -> half as many columns (axis 1) or rows (axis 0), as Pillow's BILINEAR."""
    h, w = img.shape[:2]
    n = img.shape[axis]
    kernel, anchor, size = (TAPS, (1, 0), (w // 2, h)) if axis == 1 else (TAPS.T, (0, 1), (w, h // 2))
    sums = cv2.filter2D(img, cv2.CV_16S, kernel, anchor=anchor, borderType=cv2.BORDER_CONSTANT)
    sums = cv2.resize(sums, size, interpolation=cv2.INTER_NEAREST)  # the sums at pixels 2i
    sums += 4
    sums >>= 3
    out = sums.astype(np.uint8)
    for i, (first, coefs) in zip((0, n // 2 - 1), edge_coefficients(n)):
        acc = np.int64(1 << (PRECISION_BITS - 1))
        for j, c in enumerate(coefs):
            acc = acc + np.take(img, first + j, axis=axis).astype(np.int64) * c
        edge = np.clip(acc >> PRECISION_BITS, 0, 255).astype(np.uint8)
        if axis == 1:
            out[:, i] = edge
        else:
            out[i] = edge
    return out


def resize_bilinear(rgb: np.ndarray, width: int, height: int) -> np.ndarray:
    """(H, W, 3) uint8 -> (height, width, 3): exactly ``Image.resize((width, height), BILINEAR)``."""
    h, w = rgb.shape[:2]
    if (width, height) == (w, h):
        return rgb
    if rgb.ndim == 3 and h % 2 == 0 and w % 2 == 0 and (2 * width, 2 * height) == (w, h):
        return halve_axis(halve_axis(np.ascontiguousarray(rgb), 1), 0)
    return np.asarray(Image.fromarray(rgb).resize((width, height), Image.BILINEAR))

"""The ONNX detectors' speed-only changes give the same bits as the code they replaced (issue 11).

- ``resize_bilinear`` against Pillow's ``Image.resize(BILINEAR)`` itself (random and real images);
- the separable ``bilinear_sample`` against the four-corner formula it replaced;
- the whole YOLO ``predict`` on real tum-fr1-rpy frames with the fp32 model from ../shared/models
  against the same predict with the old pieces put back (Pillow letterbox on a padded canvas,
  four-corner sampling): boxes, labels, scores and masks equal (skipped where the data is absent).
"""

from __future__ import annotations


import numpy as np
import pytest
from PIL import Image

from ltc_plugins.onnx import common as onnx_common, yolo_seg
from ltc_plugins.onnx.resize import PRECISION_BITS, edge_coefficients, resize_bilinear
from tests.shared_data import SHARED

FP32_MODEL = SHARED / "models" / "yolov8n-seg_fp32.onnx"
TUM_RGB = SHARED / "data" / "tum-fr1-rpy" / "rgb"


def pillow_resize(rgb: np.ndarray, width: int, height: int) -> np.ndarray:
    return np.asarray(Image.fromarray(rgb).resize((width, height), Image.BILINEAR))


def four_corner_sample(grid, ys, xs):
    """The bilinear sampling the detectors used before: four corners gathered per output pixel."""
    y0, y1, wy, x0, x1, wx = onnx_common.bilinear_taps(*grid.shape, ys, xs)  # the rows and columns as before
    top = grid[y0][:, x0] * (1 - wx) + grid[y0][:, x1] * wx
    bottom = grid[y1][:, x0] * (1 - wx) + grid[y1][:, x1] * wx
    return top * (1 - wy) + bottom * wy


def test_edge_coefficients_by_hand():
    # First output pixel of a halving: taps 0, 1, 2 with triangle weights 3/4, 3/4, 1/4 -> 3/7, 3/7,
    # 1/7 in 22-bit fixed point, rounded half up: 1797558.86 -> 1797559, 599186.29 -> 599186.
    (first0, k0), (first1, k1) = edge_coefficients(640)
    assert (first0, k0) == (0, (1797559, 1797559, 599186))
    assert (first1, k1) == (637, (599186, 1797559, 1797559))  # the last: taps 637..639, mirrored
    assert sum(k0) == 1 << PRECISION_BITS
    # Two pixels into one: both taps weigh 3/4, normalised to 1/2 each.
    assert edge_coefficients(2) == ((0, (1 << 21, 1 << 21)), (0, (1 << 21, 1 << 21)))


@pytest.mark.parametrize("h, w", [(480, 640), (720, 1280), (2, 2), (4, 4), (6, 4), (10, 8), (2, 6), (240, 320)])
def test_halving_is_pillows_bilinear_bit_for_bit(h, w):
    rng = np.random.default_rng(h * 1000 + w)
    for rgb in (rng.integers(0, 256, (h, w, 3), dtype=np.uint8),
                np.full((h, w, 3), 255, np.uint8),  # saturation: 8 * 255 + 4 must not wrap
                np.zeros((h, w, 3), np.uint8)):
        got = resize_bilinear(rgb, w // 2, h // 2)
        assert got.dtype == np.uint8 and got.shape == (h // 2, w // 2, 3)
        np.testing.assert_array_equal(got, pillow_resize(rgb, w // 2, h // 2))


def test_other_sizes_go_through_pillow():
    rgb = np.random.default_rng(1).integers(0, 256, (31, 47, 3), dtype=np.uint8)
    for size in [(23, 15), (20, 10), (94, 62), (47, 31)]:
        np.testing.assert_array_equal(resize_bilinear(rgb, *size), pillow_resize(rgb, *size))
    view = np.random.default_rng(2).integers(0, 256, (48, 64, 4), dtype=np.uint8)[:, :, :3]  # not contiguous
    np.testing.assert_array_equal(resize_bilinear(view, 32, 24), pillow_resize(np.ascontiguousarray(view), 32, 24))


def test_separable_bilinear_sample_is_the_four_corner_one_bit_for_bit():
    rng = np.random.default_rng(3)
    grid = rng.standard_normal((80, 80)).astype(np.float32)
    cases = [
        (np.linspace(-3.2, 85.0, 333), np.linspace(10.1, 30.7, 177)),  # beyond both edges, upsampled
        (rng.uniform(-1, 81, 50), rng.uniform(-1, 81, 60)),  # unordered
        (np.array([5.5]), np.array([79.0])),
        (np.zeros(0), np.arange(4.0)),
    ]
    for ys, xs in cases:
        got = onnx_common.bilinear_sample(grid, ys, xs)
        assert got.shape == (len(ys), len(xs))
        np.testing.assert_array_equal(got, four_corner_sample(grid, ys, xs))


def tum_frames(n: int):
    if not FP32_MODEL.is_file() or not TUM_RGB.is_dir():
        pytest.skip("../shared/models/yolov8n-seg_fp32.onnx or ../shared/data/tum-fr1-rpy is absent")
    from ltc_cli.recordings.images import load_rgb

    paths = sorted(TUM_RGB.iterdir())
    return [load_rgb(p) for p in paths[:: max(1, len(paths) // n)][:n]]


def test_real_frames_letterbox_is_pillows_canvas():
    frames = tum_frames(4)
    det = yolo_seg.YoloSegDetector.from_options(None, {"model": str(FP32_MODEL), "threads": 1})
    for rgb in frames:
        x, r, (left, top) = det.letterbox(rgb)
        canvas = np.full((320, 320, 3), 114, np.uint8)
        canvas[top : top + 240, left : left + 320] = pillow_resize(rgb, 320, 240)
        assert (r, left, top) == (0.5, 0, 40) and x.flags.c_contiguous
        np.testing.assert_array_equal(x, canvas.transpose(2, 0, 1)[None].astype(np.float32) / np.float32(255))


def test_real_frames_detections_unchanged(monkeypatch):
    frames = tum_frames(12)
    det = yolo_seg.YoloSegDetector.from_options(None, {"model": str(FP32_MODEL), "threads": 1})
    now = [det.predict(rgb) for rgb in frames]
    monkeypatch.setattr(yolo_seg, "resize_bilinear", pillow_resize)
    monkeypatch.setattr(yolo_seg, "bilinear_sample", four_corner_sample)
    before = [det.predict(rgb) for rgb in frames]
    assert sum(len(b[1]) for b in before) >= 20  # the frames do hold detections
    for a, b in zip(now, before):
        for got, expected in zip(a, b):
            assert got.dtype == expected.dtype
            np.testing.assert_array_equal(got, expected)

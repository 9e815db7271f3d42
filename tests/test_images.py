"""Image decoding (issue 11): OpenCV gives the same pixels Pillow gave, colour is decoded only when a
detector reads it, and the frames sampled for the map's set-up are not decoded a second time.

The reference decoder is Pillow, as ltc used it before (``np.asarray(Image.open(p).convert("RGB"))``
and the raw 16-bit depth array), on files the tests write with Pillow.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import ltc_plugins.readers.common as reader_common
from ltc_cli.errors import FrameError
from ltc_cli.ingest.frame_setup import frame_setup_for
from ltc_cli.recordings.images import check_rgb, load_depth, load_rgb
from ltc_cli.recordings.open import open_recording

LAP1 = Path(__file__).resolve().parent.parent / "sample_data" / "lap1"


def pillow_rgb(path) -> np.ndarray:
    return np.asarray(Image.open(path).convert("RGB"))


def photo_like(h=96, w=128, seed=0) -> np.ndarray:
    """Smooth gradients plus noise and a sharp edge: what JPEG's DCT and chroma subsampling meet."""
    rng = np.random.default_rng(seed)
    v, u = np.mgrid[0:h, 0:w]
    img = np.stack([u * 255 // w, v * 255 // h, (u + v) * 255 // (h + w)], axis=-1).astype(np.int32)
    img += rng.integers(-20, 21, img.shape)
    img[h // 3 : h // 2, w // 4 : w // 2] = (250, 10, 40)
    return np.clip(img, 0, 255).astype(np.uint8)


COLOUR_FILES = {
    "rgb.png": lambda a, p: Image.fromarray(a).save(p),
    "grey.png": lambda a, p: Image.fromarray(a[..., 1]).save(p),
    "rgba.png": lambda a, p: Image.fromarray(np.dstack([a, a[..., :1]])).save(p),
    "palette.png": lambda a, p: Image.fromarray(a).quantize(64).save(p),
    "q95_444.jpg": lambda a, p: Image.fromarray(a).save(p, quality=95, subsampling=0),
    "q75_420.jpg": lambda a, p: Image.fromarray(a).save(p, quality=75, subsampling=2),
    "q90_422.jpg": lambda a, p: Image.fromarray(a).save(p, quality=90, subsampling=1),
    "grey.jpg": lambda a, p: Image.fromarray(a[..., 0]).save(p, quality=85),
    "colour.ppm": lambda a, p: Image.fromarray(a).save(p),
}


@pytest.mark.parametrize("name", sorted(COLOUR_FILES))
def test_colour_pixels_are_pillows(tmp_path, name):
    # JPEG included: OpenCV's and Pillow's libjpeg-turbo builds decode these byte-identically here
    # (the same IDCT and upsampling); a ±1 difference would fail this test.
    path = tmp_path / name
    COLOUR_FILES[name](photo_like(), path)
    got = load_rgb(path, 128, 96)
    assert got.dtype == np.uint8 and got.shape == (96, 128, 3)
    assert np.array_equal(got, pillow_rgb(path))


@pytest.mark.parametrize("suffix", [".png", ".pgm"])
def test_depth_values_are_pillows(tmp_path, suffix):
    rng = np.random.default_rng(1)
    raw = rng.integers(0, 65536, (60, 80)).astype(np.uint16)
    raw[0, 0] = 65535
    path = tmp_path / f"d{suffix}"
    Image.fromarray(raw).save(path)
    assert np.array_equal(np.asarray(Image.open(path)).astype(np.uint16), raw)  # the file holds raw
    got = load_depth(path, 1000.0, 80, 60)
    assert got.dtype == np.float32
    assert np.array_equal(got, raw.astype(np.float32) / np.float32(1000.0))
    masked = load_depth(path, 5000.0, invalid_raw=65535)
    assert masked[0, 0] == 0 and masked[0, 1] == np.float32(raw[0, 1]) / np.float32(5000.0)


def test_cut_jpeg_is_refused_as_pillow_refuses_it(tmp_path):
    """libjpeg would fill a cut JPEG with grey; Pillow calls it truncated, and so does ltc."""
    path = tmp_path / "cut.jpg"
    COLOUR_FILES["q95_444.jpg"](photo_like(), path)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) * 2 // 3])
    with pytest.raises(FrameError, match="cannot read image .*truncated"):
        load_rgb(path)


def test_wrong_files_give_the_same_errors(tmp_path):
    depth = tmp_path / "d.png"
    Image.fromarray(np.full((6, 8), 300, np.uint16)).save(depth)
    for check in (load_rgb, check_rgb):
        with pytest.raises(FrameError, match=r"16-bit single-channel image \(mode I;16\).*depth image"):
            check(depth)
    grey = tmp_path / "g.png"
    Image.fromarray(np.full((6, 8), 3, np.uint8)).save(grey)
    with pytest.raises(FrameError, match=r"must be 16-bit single-channel, got mode L \(uint8\)"):
        load_depth(grey, 1000.0)
    with pytest.raises(FrameError, match="colour image is 8x6, the camera is 640x480"):
        check_rgb(grey, 640, 480)
    with pytest.raises(FrameError, match="image file is missing"):
        check_rgb(tmp_path / "none.png")


def counting(monkeypatch, name):
    """Count the calls of reader_common.<name> (the readers' decoder), still decoding."""
    calls = []
    real = getattr(reader_common, name)

    def wrapper(path, *args, **kwargs):
        calls.append(Path(path).name)
        return real(path, *args, **kwargs)

    monkeypatch.setattr(reader_common, name, wrapper)
    return calls


def test_colour_is_decoded_on_first_use_and_once(monkeypatch):
    calls = counting(monkeypatch, "load_rgb")
    rec = open_recording(LAP1)
    frame = rec.frames[3].load()
    assert calls == []  # loading a frame decodes its depth only
    first = frame.rgb
    assert frame.rgb is first and calls == ["000003.png"]
    assert np.array_equal(first, pillow_rgb(LAP1 / "rgb" / "000003.png"))


def test_frame_setup_frames_are_decoded_once(monkeypatch):
    calls = counting(monkeypatch, "load_depth")
    rec = open_recording(LAP1)
    n = len(rec.frames)
    frame_setup_for(rec)
    sampled = len(calls)
    assert sampled == 6  # SAMPLE_FRAMES for a z-up recording
    frames = [ref.load() for ref in rec.frames]
    assert len(calls) == n  # the 6 sampled frames were handed out, not decoded again
    again = rec.frames[0].load()  # a later load of a sampled frame reads the file anew
    assert len(calls) == n + 1 and again is not frames[0]
    assert np.array_equal(again.depth_m, frames[0].depth_m)

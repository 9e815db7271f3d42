"""COCO run-length encoding (ltc_cli/recordings/rle.py): by hand, and against pycocotools, the
COCO API's own implementation, on masks of every kind of run."""

import numpy as np
import pytest
from pycocotools import mask as coco_mask

from ltc_cli.recordings import rle


def test_a_string_by_hand():
    # Runs 5, 10, 2, 3: the first three as they are ('5' = 48 + 5, ':' = 48 + 10, '2'), then 3 - 10 =
    # -7, one 5-bit digit with the sign bit: -7 & 0x1F = 25 -> 'I' (48 + 25).
    assert rle.counts_to_string([5, 10, 2, 3]) == "5:2I"
    assert rle.string_to_counts("5:2I").tolist() == [5, 10, 2, 3]
    # 5, 10, 2, 3, 4, 13: the fifth and sixth as differences from the third and fourth, 2 and 10.
    assert rle.string_to_counts("5:2I2:").tolist() == [5, 10, 2, 3, 4, 13]
    # 100 = 0b11_00100: digits 4 (with the continuation bit, 4 | 32 = 36 -> 'T') then 3 ('3').
    assert rle.string_to_counts("T3").tolist() == [100]
    mask = rle.decode({"size": [4, 5], "counts": "5:2I"})
    assert mask.ravel(order="F").tolist() == [False] * 5 + [True] * 10 + [False] * 2 + [True] * 3


def masks():
    rng = np.random.default_rng(11)
    yield np.zeros((7, 5), dtype=bool)
    yield np.ones((7, 5), dtype=bool)  # starts with a run of 0 zeros
    yield np.eye(1, dtype=bool)
    yield rng.random((48, 64)) < 0.5  # short runs
    blob = np.zeros((480, 640), dtype=bool)  # long runs, up and down from one column to the next
    yy, xx = np.mgrid[:480, :640]
    blob[(yy - 200) ** 2 / 90.0**2 + (xx - 300) ** 2 / 160.0**2 < 1] = True
    blob[300:470, 20:25] = True
    yield blob
    yield ~blob
    for _ in range(20):
        h, w = rng.integers(1, 200, size=2)
        yield rng.random((h, w)) < rng.uniform(0.01, 0.99)


# pycocotools 2.0.11's decode warns of numpy 2's copy keyword; what it decodes is right.
@pytest.mark.filterwarnings("ignore:__array__ implementation:DeprecationWarning")
@pytest.mark.parametrize("k,mask", list(enumerate(masks())))
def test_the_coco_api_reads_what_ltc_writes_and_ltc_reads_what_it_writes(k, mask):
    coco = coco_mask.encode(np.asfortranarray(mask.astype(np.uint8)))
    ours = rle.encode(mask)
    assert ours == {"size": [int(v) for v in coco["size"]], "counts": coco["counts"].decode("ascii")}
    np.testing.assert_array_equal(coco_mask.decode({"size": ours["size"], "counts": ours["counts"].encode()}), mask)
    np.testing.assert_array_equal(rle.decode({"size": list(coco["size"]), "counts": coco["counts"].decode()}), mask)
    # The uncompressed form, a list of runs, is read as well.
    np.testing.assert_array_equal(rle.decode({"size": ours["size"], "counts": rle.encode_counts(mask)}), mask)


@pytest.mark.parametrize("text,message", [
    ("5:2" + chr(48 + 0x20), "truncated RLE string"),  # ends on a digit that says another follows
    ("5:~I", "invalid character '~' in RLE string"),
    ("5:/I", "invalid character '/' in RLE string"),
    ("5:\u00e9I", "invalid character '\u00e9' in RLE string"),
    (chr(48 + 0x20) * 13 + "1", "a run length in the RLE string is too large for an image"),
])
def test_a_broken_string_is_refused(text, message):
    with pytest.raises(ValueError, match=message):
        rle.string_to_counts(text)


def test_runs_that_do_not_fill_the_image_are_refused():
    with pytest.raises(ValueError, match="run lengths add up to 20, not 4x4 = 16"):
        rle.decode({"size": [4, 4], "counts": "5:2I"})
    with pytest.raises(ValueError, match="negative run length"):
        rle.decode({"size": [4, 4], "counts": [5, -1, 12]})

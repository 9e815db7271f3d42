"""COCO run-length encoding of binary masks (the ``{"size": [H, W], "counts": ...}`` form).

Runs alternate 0s and 1s, starting with 0s, over the mask in column-major (Fortran) order; the
compressed string form packs each run (after the first two, as a difference from the run two
before) into 5-bit groups offset by 48, with 0x20 as the continuation bit and 0x10 as the sign bit.
"""

from __future__ import annotations

import numpy as np


def encode_counts(mask: np.ndarray) -> list[int]:
    """Run lengths of a (H, W) bool mask in column-major order, starting with a run of 0s."""
    flat = np.asarray(mask, dtype=bool).ravel(order="F")
    if flat.size == 0:
        return []
    change = np.flatnonzero(flat[1:] != flat[:-1]) + 1
    bounds = np.concatenate([[0], change, [flat.size]])
    runs = np.diff(bounds).tolist()
    if flat[0]:
        runs.insert(0, 0)
    return runs


def counts_to_string(counts: list[int]) -> str:
    out = []
    for i, x in enumerate(counts):
        x = int(x)
        if i > 2:
            x -= int(counts[i - 2])
        more = True
        while more:
            c = x & 0x1F
            x >>= 5
            more = (x != -1) if (c & 0x10) else (x != 0)
            if more:
                c |= 0x20
            out.append(chr(c + 48))
    return "".join(out)


#: Characters a group of 5-bit digits may span in int64 (12 x 5 = 60 bits): a run of 2^60 pixels or
#: more is no image's.
MAX_GROUP = 12


def string_to_counts(s: str) -> np.ndarray:
    """The run lengths (int64) of a compressed string; ValueError for a character outside the
    alphabet, a string that ends inside a number, or a number too large for any image. In numpy:
    a replay decodes every mask of every frame (pure Python took 0.13 ms a tum-fr1-rpy mask)."""
    c = np.frombuffer(s.encode("utf-8"), dtype=np.uint8).astype(np.int64) - 48
    if c.size == 0:
        return np.zeros(0, dtype=np.int64)
    if ((c < 0) | (c > 63)).any():
        bad = next(ch for ch in s if not 0 <= ord(ch) - 48 <= 63)
        raise ValueError(f"invalid character {bad!r} in RLE string")
    ends = np.flatnonzero((c & 0x20) == 0)  # a digit without the continuation bit ends its number
    if ends.size == 0 or ends[-1] != c.size - 1:
        raise ValueError("truncated RLE string")
    starts = np.concatenate([[0], ends[:-1] + 1])
    lengths = ends - starts + 1
    if lengths.max() > MAX_GROUP:
        raise ValueError("a run length in the RLE string is too large for an image")
    digit = np.arange(c.size) - np.repeat(starts, lengths)  # each character's place in its number
    x = np.add.reduceat((c & 0x1F) << (5 * digit), starts)
    negative = (c[ends] & 0x10) != 0  # the sign bit of a number's last digit
    x[negative] |= -1 << (5 * lengths[negative])
    # After the first two, each run is coded as its difference from the run two before it: the
    # runs at odd places and at even places from the third on are running sums.
    x[1::2] = np.cumsum(x[1::2])
    x[2::2] = np.cumsum(x[2::2])
    return x


def encode(mask: np.ndarray) -> dict:
    """(H, W) bool mask -> {"size": [H, W], "counts": compressed string}."""
    h, w = mask.shape
    return {"size": [int(h), int(w)], "counts": counts_to_string(encode_counts(mask))}


def decode(rle: dict) -> np.ndarray:
    """{"size": [H, W], "counts": str | list[int]} -> (H, W) bool mask. Raises ValueError."""
    h, w = (int(v) for v in rle["size"])
    counts = rle["counts"]
    if isinstance(counts, str):
        counts = string_to_counts(counts)
    counts = np.asarray(counts, dtype=np.int64)
    if counts.size and counts.min() < 0:
        raise ValueError("negative run length")
    if int(counts.sum()) != h * w:
        raise ValueError(f"run lengths add up to {int(counts.sum())}, not {h}x{w} = {h * w}")
    values = (np.arange(counts.size) % 2).astype(bool)
    flat = np.repeat(values, counts)
    return flat.reshape((h, w), order="F")

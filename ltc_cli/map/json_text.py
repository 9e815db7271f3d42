"""Compact JSON text for many records of one shape, built with numpy instead of ``json``.

A *field* is the text of one value per record, as a pair of uint8 arrays ``(chars, mask)`` of shape
(..., W): the characters, padded, and which of them belong to the text. Fields are joined side by
side (:func:`cat`), made into lists (:func:`seq`) and finally packed (:func:`pack`:
``chars[mask]``), so 100,000 records of hundreds of numbers each are written without a Python loop
per number.

The text is exactly what ``json`` writes for the same values (``separators=(",", ":")``,
``ensure_ascii=False``, ``allow_nan=False``): :func:`decimals` writes a number rounded to d decimals
as ``repr`` would, in plain digits, whenever that is provably the same text (see there), and asks
``json`` itself for the rest (tiny numbers that ``repr`` writes as ``1e-05``, huge ones, NaN).
"""

from __future__ import annotations

import json

import numpy as np

_ENCODE = json.JSONEncoder(separators=(",", ":"), ensure_ascii=False, allow_nan=False).encode


def lit(text: str):
    """A literal: the same text in every record."""
    b = np.frombuffer(text.encode("utf-8"), np.uint8)
    return b, np.ones(len(b), bool)


def texts(index, table: list[str]):
    """Field: the JSON text of ``table[index]`` (a string, say) for each record."""
    raw = [_ENCODE(t).encode("utf-8") for t in table]
    width = max([len(r) for r in raw] + [1])
    chars, mask = np.zeros((len(raw), width), np.uint8), np.zeros((len(raw), width), bool)
    for i, r in enumerate(raw):
        chars[i, :len(r)] = np.frombuffer(r, np.uint8)
        mask[i, :len(r)] = True
    return chars[index], mask[index]


def booleans(values):
    """Field: true / false."""
    v = np.asarray(values, bool)
    chars = np.where(v[..., None], np.frombuffer(b"true ", np.uint8), np.frombuffer(b"false", np.uint8))
    mask = np.ones(v.shape + (5,), bool)
    mask[..., 4] = ~v
    return chars.astype(np.uint8), mask


# Digits are written three at a time, each group of three as the bytes [lead, d, d, d] of one uint32
# looked up in a table (a 1-D lookup is cheap; int64 division per digit is not). The lead byte of a
# number's first group holds its sign ("-") and that of its first decimal group the point ("."). The
# mask of each group is looked up the same way.
_TRIPLES = np.array([[0] + list(f"{i:03d}".encode()) for i in range(1000)], np.uint8).view(np.uint32)[:, 0]
# Trailing zeros of 0..999 written with three digits ("000": 3).
_TRAILING = np.array([3 if i == 0 else len(f"{i:03d}") - len(f"{i:03d}".rstrip("0")) for i in range(1000)])
# Group masks by code = 8 * lead byte shown + 4 * (digits kept on the left, not the right) + digits kept.
_MASKS = np.array([[lead] + ([True] * n + [False] * (3 - n) if left else [False] * (3 - n) + [True] * n)
                   for lead in (0, 1) for left in (0, 1) for n in range(4)], bool).view(np.uint32)[:, 0]


def _triples(m, groups: int) -> list:
    """Groups of three decimal digits (0..999) of non-negative integers m, most significant first."""
    out = []
    if m.size and m.max() >= 2 ** 50:
        for _ in range(groups):
            m, low = np.divmod(m, 1000)
            out.append(low)
    else:
        # In float64, exactly: every integer below 2**53 is a double, m / 1000 is correctly rounded
        # and, below 2**50, never rounds up to the next integer; int64 division is several times slower.
        m = m.astype(np.float64)
        for _ in range(groups):
            high = np.floor(m / 1000.0)
            out.append((m - high * 1000.0).astype(np.intp))
            m = high
    return out[::-1]


def _n_digits(m):
    """How many digits non-negative integers m have (at least 1): one comparison per digit of the
    largest (the whole parts here have one to three), cheaper than a search per number."""
    n = np.ones(np.shape(m), np.intp)
    top, p = int(np.max(m, initial=0)), 10
    while p <= top:
        n += m >= p
        p *= 10
    return n


def _whole_codes(n_digits, negative, groups: int) -> list:
    """Mask codes of the groups of an integer part of ``n_digits`` digits (right-aligned)."""
    return [8 * (negative if g == 0 else 0) + np.clip(n_digits - 3 * (groups - 1 - g), 0, 3)
            for g in range(groups)]


def _field(lows: list, codes: list, shape):
    chars = _TRIPLES[np.stack(lows, -1)].view(np.uint8)
    mask = _MASKS[np.stack(codes, -1)].view(bool)
    return chars.reshape(shape + (-1,)), mask.reshape(shape + (-1,))


def integers(values):
    """Field: integers (any int64) as json writes them."""
    v = np.asarray(values, np.int64)
    m = np.abs(v)  # -2**63 stays negative: the check below sends it to json
    ok = m >= 0
    m = np.where(ok, m, 0)
    n = _n_digits(m)
    groups = -(-int(n.max(initial=1)) // 3)
    chars, mask = _field(_triples(m, groups), _whole_codes(n, v < 0, groups), v.shape)
    chars[..., 0] = 45
    return _patch(chars, mask, ~ok, v, int)


def decimals(values, d: int):
    """Field: numbers already rounded to ``d`` (1..9) decimals (``np.round(x, d)``), as json writes them.

    json writes ``repr(v)``: the shortest decimal that reads back as v. When v is the double nearest
    to k / 10**d (checked: ``k / 10**d == v``, a correctly rounded division) and |v| < 1e6, doubles
    are closer together than 10**-d, so no other decimal of at most d places reads back as v, and
    the shortest is k / 10**d itself without trailing zeros; ``repr`` writes it in plain digits for
    1e-4 <= |v| < 1e16 (and zero). Everything else goes through json.
    """
    v = np.asarray(values, np.float64)
    scale = 10.0 ** d
    with np.errstate(invalid="ignore", over="ignore"):
        k = np.rint(v * scale)
        a = np.abs(v)
        fast = np.isfinite(v) & (a < 1e6) & ((a >= 1e-4) | (v == 0)) & (k / scale == v)
    m = np.where(fast, np.abs(k), 0).astype(np.int64)
    whole, frac = np.divmod(m, 10 ** d)
    n_int = _n_digits(whole)
    wg, fg = -(-int(n_int.max(initial=1)) // 3), -(-d // 3)
    f_lows = _triples(frac * 10 ** (3 * fg - d), fg)  # the d decimals left-aligned in fg groups
    # Decimals kept: d less the trailing zeros, at least one ("1.0").
    trailing, still = np.zeros(v.shape, np.intp), np.ones(v.shape, bool)
    for low in f_lows[::-1]:
        trailing = trailing + np.where(still, _TRAILING[low], 0)
        still &= low == 0
    kept = np.maximum(3 * fg - trailing, 1)
    f_codes = [8 * (g == 0) + 4 + np.clip(kept - 3 * g, 0, 3) for g in range(fg)]
    chars, mask = _field(_triples(whole, wg) + f_lows, _whole_codes(n_int, np.signbit(v), wg) + f_codes, v.shape)
    chars[..., 0], chars[..., 4 * wg] = 45, 46
    return _patch(chars, mask, ~fast, v, float)


def _patch(chars, mask, slow, values, kind):
    """Records where the vectorised text is not provably json's: json's own text."""
    where = np.argwhere(slow)
    if not len(where):
        return chars, mask
    raw = [_ENCODE(kind(values[tuple(ix)])).encode("ascii") for ix in where]
    width = max(max(len(r) for r in raw), chars.shape[-1])
    if width > chars.shape[-1]:
        pad = [(0, 0)] * (chars.ndim - 1) + [(0, width - chars.shape[-1])]
        chars, mask = np.pad(chars, pad), np.pad(mask, pad)
    for ix, r in zip(where, raw):
        ix = tuple(ix)
        chars[ix] = 0
        mask[ix] = False
        chars[ix][:len(r)] = np.frombuffer(r, np.uint8)
        mask[ix][:len(r)] = True
    return chars, mask


def cat(*fields):
    """Fields (and literals) side by side, record by record."""
    lead = next(f[0].shape[:-1] for f in fields if f[0].ndim > 1)
    chars = [np.broadcast_to(c, lead + c.shape[-1:]) for c, _ in fields]
    masks = [np.broadcast_to(m, lead + m.shape[-1:]) for _, m in fields]
    return np.concatenate(chars, -1), np.concatenate(masks, -1)


def seq(field, keys: list[str] | None = None):
    """Field (..., K, W) -> (..., K*(W+1)+1): a JSON list of the K values, or with ``keys`` an
    object {key: value} (keys in that order). Each value is written after one byte that is "[" (or
    "{") before the first value and "," before the others; the last byte closes the list."""
    chars, mask = field
    lead, (k, w) = chars.shape[:-2], chars.shape[-2:]
    if keys is not None:
        kc, km = texts(np.arange(k), keys)
        kc, km = np.concatenate([kc, np.full((k, 1), 58, np.uint8)], 1), np.concatenate([km, np.ones((k, 1), bool)], 1)
    else:
        kc, km = np.zeros((k, 0), np.uint8), np.zeros((k, 0), bool)
    item = 1 + kc.shape[1] + w
    out_c, out_m = np.empty(lead + (k * item + 1,), np.uint8), np.ones(lead + (k * item + 1,), bool)
    for out, src, sep in ((out_c, (kc, chars), (91 if keys is None else 123, 44)), (out_m, (km, mask), (True, True))):
        body = np.lib.stride_tricks.as_strided(  # (..., K, item) view of all but the last byte
            out, lead + (k, item), out.strides[:-1] + (item * out.strides[-1], out.strides[-1]), writeable=True)
        body[..., 0, 0] = sep[0]
        body[..., 1:, 0] = sep[1]
        body[..., 1:1 + src[0].shape[1]] = src[0]
        body[..., 1 + src[0].shape[1]:] = src[1]
    out_c[..., -1] = 93 if keys is None else 125
    return out_c, out_m


def pack(field) -> bytes:
    """The text of every record, one after the other."""
    chars, mask = field
    # np.compress, a few hundred records at a time: the same bytes as chars[mask], in a third of the
    # time (boolean indexing is slow on bytes), with an index array of a few MB, not 8 bytes per
    # character of the whole chunk.
    chars, mask = chars.reshape(-1, chars.shape[-1]), mask.reshape(-1, mask.shape[-1])
    step = max(1, (1 << 19) // max(1, chars.shape[1]))
    return b"".join(np.compress(mask[i:i + step].ravel(), chars[i:i + step].ravel()).tobytes()
                    for i in range(0, len(chars), step))

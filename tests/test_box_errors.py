"""benchmarks/bench_box_errors.py's rescoring, against XY IoUs worked out by hand."""

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
from bench_box_errors import rescored, size_ratios  # noqa: E402


def box(x, y, yaw, sx, sy):
    return np.array([x, y, 0.5]), float(yaw), np.array([sx, sy, 1.0])


def test_a_box_half_a_side_off():
    """1 x 1 m boxes 0.5 m apart along x: overlap 0.5, union 1.5, IoU 1/3; with the truth's centre
    the boxes coincide; with the truth's size or yaw they are as they were."""
    r = rescored(box(0.5, 0, 0, 1, 1), box(0, 0, 0, 1, 1))
    assert r["as mapped"] == pytest.approx(1 / 3)
    assert r["truth's centre"] == pytest.approx(1.0)
    assert r["truth's size"] == pytest.approx(1 / 3) and r["truth's yaw"] == pytest.approx(1 / 3)


def test_a_quarter_turn_with_sides_swapped_is_the_same_box():
    """2 x 1 m turned 90 degrees is the truth's 1 x 2 m: IoU 1 as mapped and with the truth's yaw
    (the sides swap with it); with the truth's size at the map's centre too."""
    r = rescored(box(0, 0, np.pi / 2, 2, 1), box(0, 0, 0, 1, 2))
    assert r["as mapped"] == pytest.approx(1.0)
    assert r["truth's yaw"] == pytest.approx(1.0)
    assert r["truth's size"] == pytest.approx(1.0)


def test_a_box_twice_too_wide():
    """2 x 1 m against the truth's 1 x 1 m at one centre: IoU 1/2; the truth's size mends it."""
    r = rescored(box(0, 0, 0, 2, 1), box(0, 0, 0, 1, 1))
    assert r["as mapped"] == pytest.approx(0.5) and r["truth's centre"] == pytest.approx(0.5)
    assert r["truth's size"] == pytest.approx(1.0)


def test_size_ratios_along_the_truths_long_and_short_sides():
    """A 0.6 x 1.5 x 1.0 m box turned 90 degrees, 0.3 m east and 0.4 m north of a 1.0 x 0.5 x 1.0 m
    truth (long side along x): turned back, its sides are 1.5 m along the truth's long side (1.5)
    and 0.6 m along the short one (1.2); height 1.0; the centres 0.5 m apart (a 3-4-5 triangle)."""
    long_, short, height, off = size_ratios((np.array([0.3, 0.4, 0.5]), np.pi / 2, np.array([0.6, 1.5, 1.0])),
                                            (np.array([0.0, 0.0, 0.5]), 0.0, np.array([1.0, 0.5, 1.0])))
    assert (long_, short, height, off) == pytest.approx((1.5, 1.2, 1.0, 0.5))


def test_size_ratios_when_the_truths_long_side_is_its_y():
    """The truth 0.5 x 2.0 m (long along y), the map 0.5 x 1.0 m at its yaw: the long side is half
    the truth's, the short one equal."""
    long_, short, _, off = size_ratios((np.zeros(3), 0.0, np.array([0.5, 1.0, 1.0])),
                                       (np.zeros(3), 0.0, np.array([0.5, 2.0, 1.0])))
    assert (long_, short, off) == pytest.approx((0.5, 1.0, 0.0))

"""benchmarks/bench_paired.py's paired bootstrap and per-house counts, against values worked out by
hand and against scipy.stats.bootstrap as a second implementation."""

import sys
from pathlib import Path

import numpy as np
from scipy import stats

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
from bench_paired import COUNTS, f1, house_counts, paired_bootstrap  # noqa: E402


def test_the_same_difference_in_every_house_has_no_spread():
    """Five houses each one object up and none down: every redraw totals 5 and 0."""
    lo, hi = paired_bootstrap(np.array([[1, 0]] * 5), draws=200)
    np.testing.assert_array_equal(lo, [5, 0])
    np.testing.assert_array_equal(hi, [5, 0])


def test_two_houses_by_hand():
    """Houses differing by 0 and 2: a redraw totals 0 (both the first), 2 or 4 (both the second),
    each with probability 1/4, so the 2.5 % and 97.5 % points are 0 and 4."""
    lo, hi = paired_bootstrap(np.array([[0], [2]]), draws=4000)
    assert (lo[0], hi[0]) == (0.0, 4.0)
    # At 40 % the middle half of the draws (all totals of 2) is all that is left.
    lo, hi = paired_bootstrap(np.array([[0], [2]]), draws=4000, level=0.4)
    assert (lo[0], hi[0]) == (2.0, 2.0)


def test_the_interval_agrees_with_scipy():
    diffs = np.array([0, 0, 1, -1, 2, 0, 0, 1, 3, 0, -1, 0, 1, 0, 0, 2, 0, 1, 0, -2] * 2, dtype=float)
    lo, hi = paired_bootstrap(diffs[:, None], draws=20000, seed=1)
    ref = stats.bootstrap((diffs,), np.sum, n_resamples=20000, method="percentile", confidence_level=0.95,
                          random_state=np.random.default_rng(2)).confidence_interval
    assert abs(lo[0] - ref.low) <= 1.0 and abs(hi[0] - ref.high) <= 1.0
    assert lo[0] < diffs.sum() < hi[0]


def test_house_counts_and_f1_by_hand():
    res = {"tp": 10, "fp": 2, "fn": 3, "at_iou": {"0.25": {"tp": 7}, "0.5": {"tp": 4}}, "ghosts": 1,
           "duplicates": 0, "deleted_while_present": {"count": 1, "present": 9}}
    counts = house_counts(res, {"kept": 8, "tracked": 9})
    assert len(counts) == len(COUNTS)
    np.testing.assert_array_equal(counts, [10, 2, 3, 7, 1, 0, 1, 1])
    assert house_counts(res, None)[6] == 0  # lap 1: no ids to keep
    assert f1(counts) == 2 * 10 / (2 * 10 + 2 + 3)

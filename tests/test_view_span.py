"""The distinct views that confirm an object (maintenance.min_detection_views), by the span of its
detection views rather than counted one after another (issue 9, twenty-first round): the same
views in any order give the same answer. Values worked out by hand."""

import numpy as np
import pytest

from ltc_cli.pipeline.views import new_view, span_views, union_span, widen_span


def view(x, y=0.0, turn_deg=0.0):
    """A camera at (x, y, 1.2) looking along +x turned by turn_deg about z: (6,) as camera_view."""
    a = np.radians(turn_deg)
    return np.array([x, y, 1.2, np.cos(a), np.sin(a), 0.0])


def span_of(views):
    span = np.zeros(12)
    for k, v in enumerate(views):
        span = widen_span(span, v, k == 0)
    return span


def greedy_count(views, min_move=0.15, min_turn=10.0):
    last, count = np.zeros(6), 0
    for v in views:
        if new_view(last[None], v, min_move, min_turn)[0]:
            count, last = count + 1, v
    return count


def test_widen_and_union_by_hand():
    """Spans hold, per coordinate, the least then the greatest: positions then forward axes along x,
    y, z, (x + y) / sqrt 2 and (x - y) / sqrt 2."""
    r = 0.5 ** 0.5
    c12, s12 = np.cos(np.radians(12)), np.sin(np.radians(12))
    span = span_of([view(0.0, 0.05), view(0.1, -0.02, 12.0)])
    lo, hi = span[:10], span[10:]
    np.testing.assert_allclose(lo[:5], [0.0, -0.02, 1.2, 0.05 * r, -0.05 * r])
    np.testing.assert_allclose(hi[:5], [0.1, 0.05, 1.2, 0.08 * r, 0.12 * r])
    np.testing.assert_allclose(lo[5:], [c12, 0, 0, r, (c12 - s12) * r])
    np.testing.assert_allclose(hi[5:], [1, s12, 0, (c12 + s12) * r, r])
    both = union_span(span, span_of([view(-0.3, 0.0)]))
    np.testing.assert_allclose(both[:3], [-0.3, -0.02, 1.2])
    np.testing.assert_allclose(both[10:13], [0.1, 0.05, 1.2])


@pytest.mark.parametrize("views, expected", [
    ([view(0.0), view(0.16)], 2),                     # 0.16 m along x
    ([view(0.0), view(0.14)], 1),                     # 0.14 m: under 0.15
    # 0.14 m along x and along y: 0.198 m along the diagonal
    ([view(0.0, 0.0), view(0.14, 0.14)], 2),
    # 0.155 m apart at 22.5 degrees from x: 0.155 cos 22.5 = 0.143 along x and along the diagonal,
    # under 0.15 (the span's bound is 8 % short at worst)
    ([view(0.0, 0.0), view(0.155 * np.cos(np.radians(22.5)), 0.155 * np.sin(np.radians(22.5)))], 1),
    # Turned 12 degrees: the forward axes differ by sin 12 = 0.208 along y, over the chord of 10
    # degrees, 2 sin 5 = 0.174; turned 9: sin 9 = 0.156, under it
    ([view(0.0), view(0.0, 0.0, 12.0)], 2),
    ([view(0.0), view(0.0, 0.0, 9.0)], 1),
    ([view(0.0)], 1),
])
def test_span_views_by_hand(views, expected):
    assert span_views(span_of(views)[None], np.array([1]), 0.15, 10.0)[0] == expected


def test_the_order_of_the_views_does_not_matter():
    """Cameras at x 0, 0.16 and 0.08: counted one after another, forward finds 0.16 new (2 views),
    backwards neither 0.16 nor 0 is 0.15 from 0.08 (1 view). The span says 2 either way."""
    forward = [view(0.0), view(0.16), view(0.08)]
    backward = [forward[2], forward[1], forward[0]]
    assert greedy_count(forward) == 2 and greedy_count(backward) == 1
    for order in (forward, backward):
        assert span_views(span_of(order)[None], np.array([greedy_count(order)]), 0.15, 10.0)[0] == 2


def test_maps_without_spans_keep_their_counts():
    """An object counted before ltc kept spans (all zeros) keeps its count; none counted: 0."""
    out = span_views(np.zeros((2, 12)), np.array([3, 0]), 0.15, 10.0)
    assert out.tolist() == [3, 0]


def test_the_span_is_kept_in_the_map_and_old_maps_read_zeros(tmp_path):
    """det_span round-trips through the map file; a map written before it (the column deleted
    here) loads with zeros, and its objects keep their counted views."""
    import h5py

    from ltc_cli.map.store import load_map, save_map
    from tests.test_store import small_map

    smap = small_map()
    span = span_of([view(0.0), view(0.16)])
    smap.objects.cols["det_span"][0] = span
    smap.objects.cols["det_views"][0] = 2
    path = tmp_path / "m.h5"
    save_map(smap, path)
    np.testing.assert_array_equal(load_map(path).objects.det_span[0], span)
    with h5py.File(path, "a") as f:
        del f["objects/det_span"]
    old = load_map(path)
    np.testing.assert_array_equal(old.objects.det_span[0], np.zeros(20))
    assert span_views(old.objects.det_span, old.objects.det_views, 0.15, 10.0).tolist() == [2]

"""association.other_class_height_ratio (issue 9, eighteenth round): of two boxes of different
classes, a taller one reaching above the bottom of the shorter, Defined one by more than its height
/ ratio is another thing, not the same object under two labels; they neither match nor merge.
Values worked out by hand."""

import numpy as np
import pytest

from ltc_cli import plugins
from ltc_cli.config import defaults, load_config
from ltc_cli.geometry.boxes import Boxes
from ltc_cli.map.model import ACTIVE, SemanticMap
from ltc_cli.pipeline.association import unlike_heights
from ltc_cli.pipeline.deduplication import merge_pairs
from ltc_cli.pipeline.mapper import Mapper

CLASSES = ["book", "bottle", "dining table"]  # then other


@pytest.mark.parametrize("short, tall, unlike", [
    # (centre z, height, Defined) of the shorter box, then of the taller one.
    ((0.535, 0.07, True), (0.635, 0.27, True), True),    # a bottle on the book's surface: 0.27 above its bottom, > 0.14
    ((0.535, 0.07, True), (0.635, 0.27, False), True),   # the same bottle seen partly: a lower bound, already too tall
    ((0.535, 0.07, False), (0.635, 0.27, True), False),  # a partial book may be part of something taller
    ((0.86, 0.30, True), (0.525, 1.05, False), False),   # a sink (0.71-1.01) called toilet with its cabinet: 0.34 < 0.6
    ((0.74, 0.49, True), (0.47, 1.02, True), False),     # a plant's leaves called bottle: 0.485 < 0.98
    ((0.05, 0.10, True), (0.10, 0.20, True), False),     # exactly twice its height above its bottom: alike
    ((0.05, 0.10, True), (0.105, 0.21, True), True),     # 0.21: unlike
    # A monitor's foot called mouse (0.75-0.80) under its screen's box (0.85-1.25): another base
    # (0.10 apart, over the foot's 0.05 m height): the stand rule's case, not judged here.
    ((0.775, 0.05, True), (1.05, 0.40, True), False),
    # The foot as mapped on a revisit (0.745-0.915, the neck with it) under a screen's box grown
    # down to 0.84: its bottom 0.095 m under the screen's, more than a quarter of its 0.17 m.
    ((0.83, 0.17, True), (1.04, 0.40, True), False),
    ((0.535, 0.07, True), (0.765, 0.27, True), False),    # a 0.27 m box 0.13 m above the book's base
])
def test_unlike_heights_by_hand(short, tall, unlike):
    assert bool(unlike_heights(*short, *tall, 0.5)) is unlike
    assert bool(unlike_heights(*tall, *short, 0.5)) is unlike  # either order
    assert not bool(unlike_heights(*short, *tall, None))  # the paper


def mapper_with(obj_size, obj_scores, cfg):
    smap = SemanticMap.new(CLASSES)
    row = smap.objects.append(center=np.array([0.0, 0.0, obj_size[2] / 2 + 0.5]), yaw=0.0, size=np.array(obj_size),
                              visible=np.ones(8, bool), defined=True, scores=np.array(obj_scores), n_det=5,
                              status=ACTIVE, first_session=0, last_session=0)
    mapper = Mapper(smap, cfg, plugins.get("metrics", "vertex").factory(cfg["association"]),
                    plugins.get("policies", "non-detection").factory(cfg["maintenance"]), session=0)
    return mapper, row


def det_box(size, defined=True):
    size = np.array([size], float)
    return Boxes(np.array([[0.0, 0.0, size[0, 2] / 2 + 0.5]]), np.zeros(1), size, np.ones((1, 8), bool)), defined


@pytest.mark.parametrize("overrides, det_size, det_class, matches", [
    # A Defined 0.08 x 0.07 x 0.27 "bottle" standing where a 0.26 x 0.19 x 0.07 book lies: its
    # vertices are 0.09-0.13 m (bottom) and 0.12-0.25 m (top) from the book's, a mean within
    # min(0.25, 1.25 x the book's 0.165 m half diagonal); the heights (0.26 of each other) part them.
    ([], [0.08, 0.07, 0.27], 1, False),
    (["association.other_class_height_ratio=null"], [0.08, 0.07, 0.27], 1, True),
    ([], [0.24, 0.18, 0.06], 1, True),    # the book itself called bottle: one height, it matches
    ([], [0.08, 0.07, 0.27], 0, True),    # a tall "book" view of the book: its own class, eq. 2 decides
])
def test_a_bottle_where_a_book_lies_is_another_object(overrides, det_size, det_class, matches):
    cfg = load_config(None, overrides)
    mapper, row = mapper_with([0.26, 0.19, 0.07], [0.9, 0.05, 0.0, 0.05], cfg)
    det, defined = det_box(det_size)
    j, _ = mapper._associate(det, det_class, np.array([row]), defined)
    assert (j == row) is matches


def test_a_partial_detection_taller_than_the_ratio_is_another_object_too():
    """The bottle seen partly (a partial 0.12 x 0.10 x 0.30 box, simulated house 203's lap 2): its
    height is a lower bound, already over twice the book's measured 0.07 m."""
    mapper, row = mapper_with([0.26, 0.19, 0.07], [0.9, 0.05, 0.0, 0.05], defaults())
    det, _ = det_box([0.12, 0.10, 0.30])
    assert mapper._associate(det, 1, np.array([row]), False)[0] == -1


def test_a_partial_map_object_is_not_judged_by_its_height():
    """A partial 0.07 m "book" map object may be the visible top of something taller: a Defined
    0.27 m bottle detection at its place still matches it by eq. 2."""
    cfg = defaults()
    mapper, row = mapper_with([0.26, 0.19, 0.07], [0.9, 0.05, 0.0, 0.05], cfg)
    mapper.map.objects.defined[row] = False
    det, _ = det_box([0.08, 0.07, 0.27])
    assert mapper._associate(det, 1, np.array([row]), True)[0] == row


def test_merges_keep_unlike_heights_apart():
    """A Defined book and a Defined bottle object at one place (XY inside it) are not merged; the
    same pair with the bottle 0.06 m tall (a book labelled bottle) is."""
    a_cfg = defaults()["association"]

    def pairs(h_bottle):
        b = Boxes(np.array([[0.0, 0.0, 0.535], [0.0, 0.0, 0.5 + h_bottle / 2]]), np.zeros(2),
                  np.array([[0.26, 0.19, 0.07], [0.08, 0.07, h_bottle]]), np.ones((2, 8), bool))
        d = plugins.get("metrics", "vertex").factory(a_cfg).distance
        return merge_pairs(b, np.array([0, 1]), d, a_cfg, None, np.array([True, True]), np.array([0, 0]), 0)

    assert pairs(0.27) == []
    assert [(a, b) for _, a, b in pairs(0.06)] == [(0, 1)]

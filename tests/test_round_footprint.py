"""``integration.round_footprint`` (issue 9, fifty-first round): two partial boxes of a thing with
no footprint direction (an office chair's five-star base) enclose in the object's own axes, the
detection's footprint taken as its inscribed ellipse, not by the rectangle around both boxes'
corners. Expected values by hand, and ``enclosing_box`` (the paper's rule) for aligned views."""

import numpy as np
import pytest

from ltc_cli.config import defaults
from ltc_cli.geometry.boxes import Box, box_corners
from ltc_cli.pipeline.class_settings import ClassSettings
from ltc_cli.pipeline.integration import enclosing_box, integrate_box, merge_objects, round_enclosing_box
from tests.mappers import mapper_with_boxes

EROSION, MIN_EXTENT = 0.01, 0.05


def box(x, y, yaw, sx, sy, z0=0.0, z1=1.0):
    return Box(np.array([x, y, (z0 + z1) / 2]), float(yaw), np.array([sx, sy, z1 - z0]), np.zeros(8, bool), False)


def test_a_view_turned_45_degrees_of_a_round_thing_does_not_grow_it():
    obj, det = box(0, 0, 0.0, 0.7, 0.7), box(0, 0, np.pi / 4, 0.7, 0.7)
    # By the corners: a square and the same square turned 45 degrees have their 8 corners on one
    # circle of radius 0.7 / sqrt(2), 45 degrees apart, a regular octagon. Its smallest rectangle
    # is the square across its flats, 2 R cos(22.5 degrees) = 0.915 on a side, less the erosion.
    across_flats = 2 * 0.7 / np.sqrt(2) * np.cos(np.pi / 8)
    assert enclosing_box(det, obj, EROSION, MIN_EXTENT).size[:2] == pytest.approx([across_flats - 0.02] * 2)
    # The ellipse inscribed in the turned square is its circle of radius 0.35: the chair stays 0.7.
    out = round_enclosing_box(det, obj, EROSION, MIN_EXTENT)
    assert out.size == pytest.approx([0.7, 0.7, 1.0])
    assert out.yaw == 0.0 and out.center == pytest.approx([0, 0, 0.5])


def test_a_long_view_turned_a_quarter_reaches_along_its_length():
    # A 1.0 x 0.4 m object and a 1.0 x 0.4 m view turned 90 degrees about the same centre: the
    # view's ellipse reaches 0.2 m along the object's x and 0.5 m along its y, so the union is 1.0
    # x 1.0 m (less the erosion, but never less than 2 x 0.5 along y, the ellipse's reach).
    obj, det = box(0, 0, 0.0, 1.0, 0.4), box(0, 0, np.pi / 2, 1.0, 0.4)
    assert round_enclosing_box(det, obj, EROSION, MIN_EXTENT).size == pytest.approx([1.0, 1.0, 1.0])


def test_an_aligned_view_encloses_as_the_paper_does():
    # The inscribed ellipse touches a box's sides along its own axes: a view aligned with the box
    # (here 0.3 m along x beyond it, and higher) encloses as enclosing_box does.
    obj, det = box(0, 0, 0.3, 0.6, 0.5), box(0.3 * np.cos(0.3), 0.3 * np.sin(0.3), 0.3, 0.6, 0.5, 0.2, 1.3)
    ours, paper = round_enclosing_box(det, obj, EROSION, MIN_EXTENT), enclosing_box(det, obj, EROSION, MIN_EXTENT)
    np.testing.assert_allclose(box_corners(ours.center, ours.yaw, ours.size),
                               box_corners(paper.center, paper.yaw, paper.size), atol=1e-9)
    assert ours.size == pytest.approx([0.88, 0.5, 1.28])  # 0.9 - 0.02, 0.5 - 0.02 (then 0.5), 1.3 - 0.02


def test_only_the_listed_classes_and_only_two_partial_boxes():
    obj, det = box(0, 0, 0.0, 0.7, 0.7), box(0, 0, np.pi / 4, 0.7, 0.7)
    assert integrate_box(det, obj, 1.0, 3.0, EROSION, MIN_EXTENT, round_footprint=True).size[0] == pytest.approx(0.7)
    across_flats = 2 * 0.7 / np.sqrt(2) * np.cos(np.pi / 8)
    assert integrate_box(det, obj, 1.0, 3.0, EROSION, MIN_EXTENT).size[0] == pytest.approx(across_flats - 0.02)
    merged, _ = merge_objects(obj, det, np.array([1.0, 0.0]), np.array([1.0, 0.0]), 3.0, 1.0, EROSION, MIN_EXTENT,
                              round_footprint=True)
    assert merged.size[0] == pytest.approx(0.7)
    # A Defined view replaces a partial box as ever.
    whole = Box(det.center, det.yaw, det.size, np.ones(8, bool), True)
    assert integrate_box(whole, obj, 1.0, 3.0, EROSION, MIN_EXTENT, round_footprint=True).yaw == pytest.approx(np.pi / 4)
    cfg = defaults()
    assert cfg["integration"]["round_footprint"] == []  # the paper's enclosing, unless asked
    cfg["integration"]["round_footprint"] = ["chair"]
    flags = ClassSettings.from_settings(["chair", "tv"], cfg).round_footprint
    assert flags.tolist() == [True, False, False]  # chair, tv, other


def test_the_mapper_encloses_a_listed_class_by_its_ellipse():
    """Stage 3 through the mapper: a partial 0.7 m "chair" object and a partial view of it turned
    45 degrees (its vertices hidden, so not Defined) grow it only when chairs are listed."""
    sizes = []
    for listed in ([], ["chair"]):
        cfg = defaults()
        cfg["integration"]["round_footprint"] = listed
        cfg["integration"]["free_space_step"] = None  # no depth in this test to carve with
        mapper = mapper_with_boxes(["chair", "tv"], cfg, [[2.0, 0.0, 0.5]], [[0.7, 0.7, 1.0]], [False],
                                   [[0.9, 0.05, 0.05]], [3])
        mapper.map.objects.cols["visible"][0] = False
        det = box(2.0, 0.0, np.pi / 4, 0.7, 0.7)
        mapper._integrate(0, det, np.array([0.9, 0.05, 0.05]), 1, "f1")
        sizes.append(mapper.map.objects.size[0].tolist())
    across_flats = 2 * 0.7 / np.sqrt(2) * np.cos(np.pi / 8)
    assert sizes[0] == pytest.approx([across_flats - 0.02, across_flats - 0.02, 1.0])
    assert sizes[1] == pytest.approx([0.7, 0.7, 1.0])

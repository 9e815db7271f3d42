"""Pixel settings are for a 640 x 480 image and scale up with a larger image
(``modeling.scale_pixels``): the same scene drawn at twice the size gives the same answers."""

import numpy as np
import pytest

from ltc_cli.config import defaults
from ltc_cli.pipeline.modeling import image_settings, model_detections, pixel_scale, scaled_px
from ltc_cli.types import Intrinsics
from tests.scene import INTR, T_world_camera, render

INTR_2X = Intrinsics(1280, 960, 2 * INTR.fx, 2 * INTR.fy, 2 * INTR.cx + 0.5, 2 * INTR.cy + 0.5)


def test_pixel_scale_and_rounding_by_hand():
    assert pixel_scale((480, 640)) == 1.0
    assert pixel_scale((720, 1280)) == 2.0  # by the longer side
    assert pixel_scale((480, 848)) == pytest.approx(1.325)
    assert pixel_scale((240, 320)) == 1.0  # smaller images keep the paper's pixels
    assert pixel_scale((720, 1280), scale=False) == 1.0
    assert [scaled_px(n, 2.0) for n in (0, 2, 5, 10)] == [0, 4, 10, 20]
    assert [scaled_px(n, 0.5) for n in (0, 1, 2, 5, 10)] == [0, 1, 1, 3, 5]  # half up; 1 stays 1
    assert scaled_px(5, 1.325) == 7  # 6.625


def test_image_settings_scale_the_pixel_counts_only():
    p = defaults()["modeling"]
    same, s = image_settings(p, (480, 640))
    assert same is p and s == 1.0
    big, s = image_settings(p, (720, 1280))
    assert s == 2.0
    assert (big["thin_max_iterations"], big["border"], big["occlusion_window"]) == (10, 20, 4)
    assert {k: v for k, v in big.items() if k not in ("thin_max_iterations", "border", "occlusion_window")} == \
        {k: v for k, v in p.items() if k not in ("thin_max_iterations", "border", "occlusion_window")}
    assert p["thin_max_iterations"] == 5  # the settings themselves are not changed
    fixed, s = image_settings({**p, "scale_pixels": False}, (720, 1280))
    assert s == 1.0 and fixed["border"] == 10


def _left_corners_visible(intr, p):
    # A cabinet's front face, 2 m ahead, seen alone: its box is padded to min_extent (0.05 m) about
    # the face, so its front corners stand 1.975 m ahead. The left ones (y = 1.234 m) are drawn 7 px
    # from the image's left edge at 640 x 480 (u = 319.5 - 500 * 1.234 / 1.975), within the 10 px
    # border, and 14.6 px at twice the size.
    depth, masks = render([(2.0, 2.4, 0.9, 1.234, 0.2, 1.0)], wall_x=4.0, intr=intr)
    out = model_detections(masks, depth, intr, T_world_camera(), p, (0.3, 6.0))
    assert len(out.source) == 1
    corners = out.boxes.corners[0]
    left = corners[:, 1] > corners[:, 1].mean()
    front = corners[:, 0] < corners[:, 0].mean()
    return out.boxes.visible[0][left & front]


def test_the_border_test_gives_the_same_answer_at_twice_the_size():
    p = defaults()["modeling"]
    assert not _left_corners_visible(INTR, p).any()
    assert not _left_corners_visible(INTR_2X, p).any()  # 14.5 px of 1280: within 20
    # Counted in pixels of any image (the paper's), the corners 14.5 px from the edge pass the 10 px
    # border at twice the size, and the cabinet's width looks observed.
    assert _left_corners_visible(INTR_2X, {**p, "scale_pixels": False}).all()

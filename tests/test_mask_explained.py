"""modeling.min_mask_explained: a box that neither had depth on most of its mask nor covers most
of it in the image is of what the mask bled onto (tum-fr1-rpy: the clutter in front of a dark
monitor became a "laptop" 0.7 m in front of it)."""

import numpy as np
import pytest

from ltc_cli.config import defaults
from ltc_cli.geometry.boxes import box_corners
from ltc_cli.geometry.camera import invert_pose, transform
from ltc_cli.pipeline.modeling import mask_coverage, model_detections
from tests.scene import INTR, T_world_camera, face_rect, render

# A dark monitor's screen (no depth) 2.5 m ahead, 0.6 m wide, z 0.9-1.3 m, and right under it in
# the image a heap of papers 2.0 m ahead (0.3 m wide, z 0.75-0.92 m) that the mask bleeds onto.
SCREEN = (2.5, 2.55, -0.3, 0.3, 0.9, 1.3)
CLUTTER = (2.0, 2.2, -0.15, 0.15, 0.75, 0.92)


def rect_mask(*faces):
    mask = np.zeros((INTR.height, INTR.width), bool)
    for x0, _, y0, y1, z0, z1 in faces:
        u0, u1, v0, v1 = face_rect(y0, y1, z0, z1, x0)
        mask[v0:v1, u0:u1] = True
    return mask


def test_mask_coverage_by_hand():
    # The screen's box, seen face on: its outline in the image is its front face, u 259.5-379.5,
    # v 179.5-259.5 (fx = fy = 500, 2.5 m: 0.6 m -> 120 px, 0.4 m -> 80 px; pixels 259-379 and
    # 179-259 have their centres on or inside it).
    x0, x1, y0, y1, z0, z1 = SCREEN
    corners_map = box_corners(np.array([(x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2]), 0.0,
                              np.array([x1 - x0, y1 - y0, z1 - z0]))
    corners_cam = transform(invert_pose(T_world_camera()), corners_map)
    assert face_rect(y0, y1, z0, z1, x0) == (259, 380, 179, 260)
    face = np.ones((81, 121), bool)
    assert mask_coverage(corners_cam, face, 179, 259, INTR) == pytest.approx(1.0)
    # The same face and as much again beside it: half of the mask is inside the outline.
    wide = np.ones((81, 242), bool)
    assert mask_coverage(corners_cam, wide, 179, 259, INTR) == pytest.approx(0.5)
    # A mask wholly below the outline: none.
    assert mask_coverage(corners_cam, face, 300, 259, INTR) == 0.0
    # A box around the camera explains any mask (no outline to draw).
    behind = corners_cam.copy()
    behind[:4, 2] = -0.5
    assert mask_coverage(behind, face, 300, 259, INTR) == 1.0


def test_a_dark_screens_mask_on_the_clutter_in_front_gives_no_box():
    depth, _ = render([SCREEN, CLUTTER], wall_x=4.0)
    mask = rect_mask(SCREEN, CLUTTER)
    screen_only = rect_mask(SCREEN)
    depth[screen_only] = 0.0  # the dark screen gives no reading
    # Pixels: the screen 121 x 81 = 9,801, the clutter 75 x 43 = 3,225 (rows 259-301, the first
    # shared with the screen): a quarter of the mask has depth, and the clutter's box covers
    # about that quarter of it.
    assert mask.sum() == 9801 + 3225 - 75
    p = dict(defaults()["modeling"])
    assert p["min_mask_explained"] == 0.5
    p["min_mask_explained"] = None
    out = model_detections([mask], depth, INTR, T_world_camera(), p, (0.3, 6.0))
    # The paper's behaviour: a box on the clutter, half a metre in front of the screen.
    assert len(out.source) == 1
    assert out.boxes.center[0, 0] == pytest.approx(2.0, abs=0.05)  # the front face seen
    p["min_mask_explained"] = 0.5
    assert len(model_detections([mask], depth, INTR, T_world_camera(), p, (0.3, 6.0)).source) == 0
    # A lower bar (a fifth of the mask) keeps it.
    p["min_mask_explained"] = 0.2
    assert len(model_detections([mask], depth, INTR, T_world_camera(), p, (0.3, 6.0)).source) == 1


def test_sparse_depth_spread_over_the_screen_keeps_its_box():
    """Both shares must be low: a screen with depth on every third column only (a third of its
    mask) gives a box over the whole screen, which explains the mask."""
    depth, _ = render([SCREEN], wall_x=4.0)
    mask = rect_mask(SCREEN)
    holes = mask.copy()
    holes[:, ::3] = False
    depth[holes] = 0.0
    p = dict(defaults()["modeling"])
    out = model_detections([mask], depth, INTR, T_world_camera(), p, (0.3, 6.0))
    assert len(out.source) == 1
    assert out.boxes.center[0, 0] == pytest.approx(2.5, abs=0.06)
    assert out.boxes.size[0, :2].max() == pytest.approx(0.6, abs=0.05)


def test_a_strip_of_depth_in_the_middle_of_a_screen_by_hand():
    """Depth on a central strip four tenths of the screen's width. Thinning takes 5 px off each
    side of the 121 x 81 px mask (111 x 71 left, 7,881 px, subsampled at stride 3); the strip is
    48 px of the 111, a share of 0.43, and its sampled columns span 45 px. The box is regrown by
    the thinning band and half a stride (5 + 1 px) per side: 57 px of the 111 columns, coverage
    0.51, so the box explains the mask at 0.5 and is kept; at 0.6 it goes."""
    depth, _ = render([SCREEN], wall_x=4.0)
    mask = rect_mask(SCREEN)
    u0, u1 = 259, 380
    strip, mid = (u1 - u0) // 10, (u0 + u1) // 2
    holes = mask.copy()
    holes[:, mid - 2 * strip : mid + 2 * strip] = False
    depth[holes] = 0.0
    p = dict(defaults()["modeling"])
    out = model_detections([mask], depth, INTR, T_world_camera(), p, (0.3, 6.0))
    assert len(out.source) == 1
    assert out.boxes.size[0, :2].max() == pytest.approx(57 * 2.5 / 500, abs=0.005)
    p["min_mask_explained"] = 0.6
    assert len(model_detections([mask], depth, INTR, T_world_camera(), p, (0.3, 6.0)).source) == 0

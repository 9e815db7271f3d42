"""Free-space carving (integration.free_space_step, issue 9 twenty-seventh round): a side of a
detected object's box that the frame's depth sees through moves in, never past the frame's own
detection. Scenes from tests/scene.py (camera looking along +x, depth = x); expected boxes worked
out by hand."""

import numpy as np
import pytest

from ltc_cli import plugins
from ltc_cli.config import defaults
from ltc_cli.geometry.boxes import Box, Boxes, box_corners
from ltc_cli.geometry.camera import invert_pose
from ltc_cli.ingest.remote import pack_depth, unpack_depth
from ltc_cli.map.model import ACTIVE, SemanticMap
from ltc_cli.pipeline.carving import carve_box, grid_pixel, seen_through, slice_points
from ltc_cli.pipeline.frame_modeling import FrameModel
from ltc_cli.pipeline.mapper import Mapper
from ltc_cli.pipeline.modeling import ModeledDetections
from tests.scene import INTR, T_world_camera, render

# The camera stands at (0, 1, 1), beside the things it looks at, so the rays to the space at
# y 0.2 - 0.6 beside the object pass no front face of it (at x = 2.0 a ray to (2.367, 0.225) is at
# y 0.345) and end on the wall at x = 4.
T_CAM = T_world_camera(cam_y=1.0)
OBJECT = (2.0, 2.4, -0.2, 0.2, 0.5, 1.2)  # x0, x1, y0, y1, z0, z1
DETECTION = Box(np.array([2.2, 0.0, 0.85]), 0.0, np.array([0.4, 0.4, 0.7]), np.ones(8, bool), True)
# The map's box of it reaches 0.4 m too far in +y: y -0.2 - 0.6.
GROWN = Box(np.array([2.2, 0.2, 0.85]), 0.0, np.array([0.4, 0.8, 0.7]), np.ones(8, bool), False)


def table_mapper(cfg, visible):
    """(mapper, map, row): a map holding GROWN as a partial "dining table" of 5 detections (vertex
    metric, static policy, so that only integration and carving change it)."""
    smap = SemanticMap.new(["cup", "dining table"])
    row = smap.objects.append(center=GROWN.center, yaw=0.0, size=GROWN.size, visible=np.full(8, visible),
                              defined=False, scores=np.array([0.0, 1.0, 0.0]), n_det=5, status=ACTIVE)
    mapper = Mapper(smap, cfg, plugins.get("metrics", "vertex").factory(cfg["association"]),
                    plugins.get("policies", "static").factory(cfg["maintenance"]))
    mapper.index.insert(row, GROWN.center, GROWN.size)
    return mapper, smap, row


def footprint_y(t, row):
    """The world y extent [min, max] of a map object's box."""
    y = box_corners(t.center[row], t.yaw[row], t.size[row])[:, 1]
    return [y.min(), y.max()]


def carve(depth, max_share=0.5, box=GROWN, ray_step=1):
    return carve_box(box, DETECTION, invert_pose(T_CAM), depth, INTR, 0.05, max_share, 0.1, ray_step)


def test_slice_points_by_hand():
    """A 2 x 2 grid on the mid-plane of the 0.1 m slice along the +y side of a 1 x 2 x 1 box at the
    origin: y = 1 - 0.05, x = -0.25 / 0.25, z = -0.25 / 0.25; turned 90 degrees, x and y swap."""
    pts = slice_points(np.zeros(3), 0.0, np.array([1.0, 2.0, 1.0]), 1, 1.0, 0.1, (2, 2))
    assert np.allclose(sorted(map(tuple, pts)), [(-0.25, 0.95, -0.25), (-0.25, 0.95, 0.25),
                                                 (0.25, 0.95, -0.25), (0.25, 0.95, 0.25)])
    turned = slice_points(np.zeros(3), np.pi / 2, np.array([1.0, 2.0, 1.0]), 1, 1.0, 0.1, (2, 2))
    assert np.allclose(sorted(map(tuple, turned)), [(-0.95, -0.25, -0.25), (-0.95, -0.25, 0.25),
                                                    (-0.95, 0.25, -0.25), (-0.95, 0.25, 0.25)])


def test_seen_through_by_hand():
    """From the camera at (0, 1, 1): (3, 1, 1) is on the optical axis, the wall at 4 behind it
    (free); (2.0, -0.1, 0.8) lies on the object's front face (read, not free); (2.3, 0, 0.8) is
    behind that face (read, hidden, not free); (-1, 1, 1) is behind the camera (no reading)."""
    depth, _ = render([OBJECT], cam_y=1.0)
    pts = np.array([[3.0, 1.0, 1.0], [2.0, -0.1, 0.8], [2.3, 0.0, 0.8], [-1.0, 1.0, 1.0]])
    free, read = seen_through(pts, invert_pose(T_CAM), depth, INTR, 0.1)
    assert free.tolist() == [True, False, False, False]
    assert read.tolist() == [True, True, True, False]


def test_a_side_seen_through_moves_in_to_the_detection():
    """Every slice of the +y side (y 0.575 down to 0.225) is seen through to the wall: 8 steps of
    0.05 m (0.4 m) bring the box to the detection's y 0.2, where it stops though 0.6 of the 0.8 m
    side (0.48 m) would allow a ninth; the other sides lie on the detection's and stay: x 2.0 - 2.4,
    y -0.2 - 0.2."""
    depth, _ = render([OBJECT], cam_y=1.0)
    out = carve(depth, max_share=0.6)
    assert np.allclose(out.center, [2.2, 0.0, 0.85])
    assert np.allclose(out.size, [0.4, 0.4, 0.7])
    assert out.yaw == GROWN.yaw and not out.defined


def test_one_frame_carves_at_most_max_share():
    """max_share 0.3 of the 0.8 m side: 0.24 m, four steps of 0.05: y -0.2 - 0.4."""
    depth, _ = render([OBJECT], cam_y=1.0)
    out = carve(depth, max_share=0.3)
    assert np.allclose(out.center, [2.2, 0.1, 0.85])
    assert np.allclose(out.size, [0.4, 0.6, 0.7])


@pytest.mark.parametrize("scene", ["something there", "no depth"])
def test_a_side_not_seen_through_stays(scene):
    """A second thing at y 0.25 - 0.8 (its front face at x 2.0 hides every point of the slices
    behind it), or no depth reading at all: the box is the one given."""
    if scene == "something there":
        depth, _ = render([OBJECT, (2.0, 2.4, 0.25, 0.8, 0.5, 1.2)], cam_y=1.0)
    else:
        depth = np.zeros((INTR.height, INTR.width), np.float32)
    assert carve(depth) is GROWN


def test_the_box_turned_against_the_detection_is_carved_in_its_own_axes():
    """The same box turned a quarter turn (its x along the world's y): the same footprint, and the
    same cut, along its own x now."""
    turned = Box(GROWN.center.copy(), np.pi / 2, np.array([0.8, 0.4, 0.7]), np.ones(8, bool), False)
    depth, _ = render([OBJECT], cam_y=1.0)
    out = carve(depth, box=turned)
    assert np.allclose(out.center, [2.2, 0.0, 0.85])
    assert np.allclose(out.size, [0.4, 0.4, 0.7])


def test_grid_pixel_is_a_pixel_stage_4_reads():
    """ray_step 8 on 640 columns: blocks 0-7, 8-15, ... read at columns 3, 11, ...; the last block
    (632-639) at 635. On 645 columns the block 640-644 has its ray at 643.5 (read at 643); on 643
    columns 643.5 is past the image, and its columns 640-642 go with the block before (635)."""
    assert grid_pixel(np.array([0.0, 3.0, 7.4, 7.6, 639.0]), 8, 640).tolist() == [3, 3, 3, 11, 635]
    assert grid_pixel(np.array([644.0]), 8, 645).tolist() == [643]
    assert grid_pixel(np.array([644.0]), 8, 643).tolist() == [635]  # 643.5 is past the image


def test_a_dask_worker_s_sparse_depth_carves_the_same():
    """A Dask worker sends back only the depth pixels stage 4 reads (ingest/remote.py); read at
    those pixels, the carving is the same as on the whole image."""
    depth, _ = render([OBJECT], cam_y=1.0)
    sparse = unpack_depth(pack_depth(depth, INTR, 8), depth.shape, INTR, 8)
    full, from_sparse = carve(depth, ray_step=8), carve(sparse, ray_step=8)
    assert np.allclose(full.size, [0.4, 0.4, 0.7])
    assert np.array_equal(full.center, from_sparse.center) and np.array_equal(full.size, from_sparse.size)


def test_only_a_detection_that_shaped_the_box_carves_it():
    """Through the mapper: a partial "dining table" map object 0.4 m too wide in +y (x 2.0-2.4,
    y -0.2-0.6) and the frame's depth seeing through its +y part. A table detection of the real
    part (x 2.0-2.4, y -0.2-0.2, seen from (0, 1, 1)) shapes it, and the side moves in: by 0.3 of
    the 0.8 m side at most, in steps of 0.05 m, 0.2 m (the part beyond the detection is seen
    through), to y -0.2-0.4. A "cup" detection integrated into it (another class, 0.07 of its
    volume: foreign geometry, only its class evidence fuses) did not shape it, and would carve
    nothing (integration returns False)."""
    cfg = defaults()
    mapper, smap, row = table_mapper(cfg, True)
    cup = Box(np.array([2.2, 0.2, 0.85]), 0.0, np.array([0.2, 0.2, 0.3]), np.ones(8, bool), True)
    assert mapper._integrate(row, cup, np.array([1.0, 0.0, 0.0]), 0, "0") is False
    np.testing.assert_array_equal(smap.objects.size[row], GROWN.size)
    depth, masks = render([OBJECT], cam_y=1.0)
    mapper.process_frame(1, "1", masks, [np.array([0.0, 1.0, 0.0])], depth, T_CAM, INTR, (0.3, 6.0))
    t = smap.objects
    assert t.status[row] == ACTIVE and t.n_det[row] == 7
    # The world's y extent (the enclosing with the modeled view, which turns the box's axes a quarter
    # turn and pads its x side to 0.405 m, leaves y -0.2-0.6 as it was: the setting off shows it).
    np.testing.assert_allclose(footprint_y(t, row), [-0.2, 0.4], atol=1e-9)
    cfg["integration"]["free_space_step"] = None
    mapper, smap, row = table_mapper(cfg, True)
    mapper.process_frame(1, "1", masks, [np.array([0.0, 1.0, 0.0])], depth, T_CAM, INTR, (0.3, 6.0))
    np.testing.assert_allclose(footprint_y(smap.objects, row), [-0.2, 0.6], atol=1e-9)


@pytest.mark.parametrize("pieces, y_max", [
    # Two pieces of the table in one frame (a split mask): y -0.2-0.0 and y 0.3-0.5. The depth sees
    # through everything (only the wall), so the +y side goes in to the second piece's face, y 0.5
    # (two steps), not further.
    (2, 0.5),
    # The first piece alone bounds nothing on that side: 0.3 of the 0.8 m side, four steps, y 0.4.
    (1, 0.4),
])
def test_every_piece_a_frame_saw_bounds_the_carving(pieces, y_max):
    """Stage 1 given (as a Dask worker sends it): partial table detections inside the map object's
    partial box (x 2.0-2.4, y -0.2-0.6) join it by containment, shape it, and together bound the
    cut."""
    mapper, smap, row = table_mapper(defaults(), False)
    centers = np.array([[2.2, -0.1, 0.85], [2.2, 0.4, 0.85]])[:pieces]
    boxes = Boxes(centers, np.zeros(pieces), np.tile([0.4, 0.2, 0.7], (pieces, 1)), np.zeros((pieces, 8), bool))
    stage1 = FrameModel(pieces, [np.array([0.0, 1.0, 0.0])] * pieces,
                        ModeledDetections(boxes, np.zeros(pieces, bool), np.arange(pieces), np.full(pieces, 100)))
    wall = np.full((INTR.height, INTR.width), 4.0, np.float32)
    res = mapper.process_frame(0, "0", [], [], wall, T_CAM, INTR, (0.3, 6.0), stage1=stage1)
    assert res.created == 0 and smap.objects.n_det[row] == 5 + pieces
    np.testing.assert_allclose(footprint_y(smap.objects, row), [-0.2, y_max], atol=1e-9)

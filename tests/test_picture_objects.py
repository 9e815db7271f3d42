"""A map object most of whose detections lay flat on a wall is a picture (modeling.picture_object_share):
the counting of flat detections on the objects they fall in, and the removal. Values by hand."""

import numpy as np

from ltc_cli import plugins
from ltc_cli.config import defaults
from ltc_cli.geometry.boxes import Boxes
from ltc_cli.map.model import ACTIVE, REMOVED, SemanticMap
from ltc_cli.pipeline.frame_modeling import ClassFlags, model_frame
from ltc_cli.pipeline.mapper import Mapper
from ltc_cli.pipeline.pictures import PICTURE_MARGIN, is_picture, mask_point, picture_hits
from tests.scene import INTR, T_world_camera, render
from tests.test_identity import CLASSES

POSTER = (3.99, 4.0, -0.3, 0.3, 0.9, 1.4)  # 1 cm proud of the wall at x = 4 (render()'s format)
TV = (3.7, 3.9, -0.3, 0.3, 0.9, 1.4)  # a screen standing 0.3 m in front of it


def tv_vector():
    v = np.full(len(CLASSES) + 1, 0.1 / 9)
    v[1], v[-1] = 0.9, 0.0  # "class1" plays the tv
    return v


def test_picture_hits_by_hand():
    """A box 0.1 x 0.6 x 0.5 m at (4, 0, 1.15), yaw 0, grown by 0.1 m: x within 3.85-4.15, y within
    -0.4-0.4, z within 0.8-1.5. Turned by 90 degrees its 0.6 m side lies along x (3.6-4.4) and its
    0.1 m side along y (-0.15-0.15)."""
    def box(yaw):
        return Boxes(np.array([[4.0, 0.0, 1.15]]), np.array([yaw]), np.array([[0.1, 0.6, 0.5]]), np.ones((1, 8), bool))

    points = np.array([[4.14, 0.39, 1.49],   # inside the grown box, near its corner
                       [4.16, 0.0, 1.15],    # 1 cm beyond it in x
                       [4.0, 0.0, 1.52],     # 2 cm above it
                       [4.3, 0.1, 1.15]])    # in the turned box only
    top = np.array([1, 1, 1, 1])
    assert picture_hits(box(0.0), np.array([1]), points, top, 0.1).tolist() == [1]
    # Turned: (4.14, 0.39) is 0.39 m off in y (> 0.15); (4.16, 0), (4.0, 0) and (4.3, 0.1) lie in
    # it by x and y, and (4.0, 0, 1.52) is above it.
    assert picture_hits(box(np.pi / 2), np.array([1]), points, top, 0.1).tolist() == [2]
    # A flat detection of another class does not count on it.
    assert picture_hits(box(0.0), np.array([2]), points, top, 0.1).tolist() == [0]
    assert picture_hits(box(0.0), np.array([1]), np.zeros((0, 3)), top[:0], 0.1).tolist() == [0]


def test_is_picture_by_hand():
    """At least 2 flat, and at least a share of all detections, flat ones included. Share 0.5:
    2 of 2 + 2 = 4 is 0.5 (a picture); 2 of 3 + 2 = 5 is 0.4 (not); 1 of 0 + 1 is all, but under 2;
    10 of 10 + 10 is 0.5. Share 0.33: 2 of 5 + 2 = 7 is 0.286 (not), 2 of 4 + 2 = 6 is 0.333."""
    n_det, n_flat = np.array([2, 3, 0, 10]), np.array([2, 2, 1, 10])
    assert is_picture(n_det, n_flat, 0.5, 2).tolist() == [True, False, False, True]
    assert is_picture(n_det, n_flat, 0.5, 1).tolist() == [True, False, True, True]
    assert is_picture(np.array([5, 4]), np.array([2, 2]), 0.33, 2).tolist() == [False, True]


def test_mask_point_of_a_poster():
    """The poster's pixels all read 3.99 m; its face spans y -0.3..0.3 and z 0.9..1.4 seen from
    (0, 0, CAM_Z): the median point is its middle, (3.99, 0, 1.15), to a pixel's width (< 1 cm)."""
    depth, masks = render([POSTER], wall_x=4.0)
    point = mask_point(masks[0], depth, INTR, T_world_camera())
    np.testing.assert_allclose(point, [3.99, 0.0, 1.15], atol=0.01)
    assert mask_point(np.zeros_like(masks[0]), depth, INTR, T_world_camera()) is None


def test_stage_1_keeps_the_point_and_class_of_a_dropped_poster():
    cfg = defaults()
    depth, masks = render([POSTER], wall_x=4.0)
    stage1 = model_frame(masks, [tv_vector()], depth, T_world_camera(), INTR, (0.3, 6.0), cfg,
                         ClassFlags.from_settings(CLASSES, cfg))
    assert len(stage1.modeled.source) == 0 and stage1.flat_top.tolist() == [1]
    np.testing.assert_allclose(stage1.flat_xyz, [[3.99, 0.0, 1.15]], atol=0.01)
    depth, masks = render([TV], wall_x=4.0)  # standing out from the wall: modeled, no flat point
    stage1 = model_frame(masks, [tv_vector()], depth, T_world_camera(), INTR, (0.3, 6.0), cfg,
                         ClassFlags.from_settings(CLASSES, cfg))
    assert len(stage1.modeled.source) == 1 and len(stage1.flat_xyz) == 0


def mapper_with_tv(cfg, n_det, center=(3.95, 0.0, 1.15)):
    """A "tv" of session 0 (Defined, 0.1 x 0.6 x 0.5 m) that a poster's earlier views made."""
    smap = SemanticMap.new(CLASSES)
    row = smap.objects.append(center=np.array(center), yaw=0.0, size=np.array([0.1, 0.6, 0.5]),
                              visible=np.ones(8, bool), defined=True, scores=tv_vector(), n_det=n_det,
                              status=ACTIVE, first_session=0, last_session=0)
    mapper = Mapper(smap, cfg, plugins.get("metrics", "vertex").factory(cfg["association"]),
                    plugins.get("policies", "non-detection").factory(cfg["maintenance"]), session=1)
    return mapper, row


def poster_frames(mapper, n):
    depth, masks = render([POSTER], wall_x=4.0)
    for k in range(n):
        mapper.process_frame(k, str(k), masks, [tv_vector()], depth, T_world_camera(), INTR, (0.3, 6.0))


def test_an_object_whose_detections_lay_flat_is_removed_as_a_picture():
    """2 detections made it; its first flat one gives 1 of 3 (under picture_min_views 2), its second
    2 of 4 = 0.5 (picture_object_share 0.5): removed then, by a "picture:" event."""
    cfg = defaults()
    assert (cfg["modeling"]["picture_object_share"], cfg["modeling"]["picture_min_views"]) == (0.5, 2)
    cfg["maintenance"]["policy"] = "static"  # no removal but the picture rule's
    mapper, row = mapper_with_tv(cfg, n_det=2)
    t = mapper.map.objects
    poster_frames(mapper, 1)
    assert (t.n_flat[row], t.status[row]) == (1, ACTIVE)
    poster_frames(mapper, 1)
    assert (t.n_flat[row], t.status[row]) == (2, REMOVED)
    removed = [e for e in mapper.map.events if e.kind == "removed"]
    assert len(removed) == 1 and removed[0].detail.startswith("picture: 2 detections")


def test_an_object_detected_often_outlives_a_few_flat_views():
    """With 10 detections, 9 flat ones are 9 of 19 = 0.47: it stays; the tenth makes 10 of 20 = 0.5."""
    cfg = defaults()
    mapper, row = mapper_with_tv(cfg, n_det=10)
    t = mapper.map.objects
    poster_frames(mapper, 9)
    assert (t.n_flat[row], t.status[row]) == (9, ACTIVE)
    poster_frames(mapper, 1)
    assert t.status[row] == REMOVED


def test_flat_detections_elsewhere_or_with_the_setting_off_count_nothing():
    cfg = defaults()
    # The object's box 0.25 m in front of the poster's point: 3.85 + 0.05 + 0.1 = 4.0 reaches 3.99...
    mapper, row = mapper_with_tv(cfg, n_det=4, center=(3.85, 0.0, 1.15))
    poster_frames(mapper, 2)
    assert mapper.map.objects.n_flat[row] == 2
    # ... 3.8 + 0.05 + PICTURE_MARGIN = 3.95 does not.
    mapper, row = mapper_with_tv(cfg, n_det=4, center=(3.8, 0.0, 1.15))
    poster_frames(mapper, 3)
    assert mapper.map.objects.n_flat[row] == 0 and mapper.map.objects.status[row] == ACTIVE
    assert PICTURE_MARGIN == 0.1
    cfg["modeling"]["picture_object_share"] = None
    mapper, row = mapper_with_tv(cfg, n_det=4)
    poster_frames(mapper, 3)
    assert mapper.map.objects.n_flat[row] == 0 and mapper.map.objects.status[row] == ACTIVE


def test_a_tv_on_the_wall_is_never_counted_as_a_picture():
    """A wall-mounted screen 1 x 0.6 m standing 5 cm (or 3 cm) proud of the wall 4 m away: its
    pixels lie 0.05 m off the wall's plane, over the fixed 0.025 m of the test of how far a
    detection stands out. Modeled, and no flat point to count; a 1 cm poster of that size is flat."""
    cfg = defaults()
    flags = ClassFlags.from_settings(CLASSES, cfg)
    for proud, flat in ((0.05, False), (0.03, False), (0.01, True)):
        depth, masks = render([(4.0 - proud, 4.0, -0.5, 0.5, 0.9, 1.5)], wall_x=4.0)
        stage1 = model_frame(masks, [tv_vector()], depth, T_world_camera(), INTR, (0.3, 6.0), cfg, flags)
        assert (len(stage1.flat_xyz), len(stage1.modeled.source)) == ((1, 0) if flat else (0, 1))

"""Confirmation from distinct views (maintenance.min_detection_views, issue 9 seventh round): an
object made in a session stays only if detections from at least two views confirm it, views being
confirm_min_move metres or confirm_min_turn degrees apart. Counts worked out by hand per case."""

import numpy as np
import pytest

from ltc_cli import plugins
from ltc_cli.config import defaults
from ltc_cli.map.model import ACTIVE, REMOVED, SemanticMap
from ltc_cli.pipeline.maintenance import unconfirmed
from ltc_cli.pipeline.mapper import Mapper
from tests.scene import INTR, T_world_camera, render
from tests.test_identity import CHAIR_FACE, CLASSES, chair_vector


def mapper_for(min_views):
    cfg = defaults()
    cfg["maintenance"]["min_detection_views"] = min_views
    cfg["maintenance"]["confirm_min_move"] = 0.15
    cfg["maintenance"]["confirm_min_turn"] = 10
    return Mapper(SemanticMap.new(CLASSES), cfg, plugins.get("metrics", "vertex").factory(cfg["association"]),
                  plugins.get("policies", "non-detection").factory(cfg["maintenance"]), session=0)


def detect_from(mapper, cam_ys):
    for k, y in enumerate(cam_ys):
        depth, masks = render([CHAIR_FACE], wall_x=4.0, cam_y=y)
        res = mapper.process_frame(k, str(k), [masks[0]], [chair_vector(0.8)], depth, T_world_camera(cam_y=y),
                                   INTR, (0.3, 6.0))
        assert res.matched + res.created == 1
    return mapper.map.objects


@pytest.mark.parametrize("cam_ys, views", [
    ((0.0, 0.0, 0.0), 1),        # three detections from one place: one view
    ((0.0, 0.1, 0.2), 2),        # 0.1 m from the counted view: not new; 0.2 m: new
    ((0.0, 0.1, 0.14), 1),       # never 0.15 m from the counted view (frame 0)
    ((0.0, 0.2, 0.3, 0.4), 3),   # 0.2 from 0 counts, 0.3 is 0.1 from 0.2: no, 0.4 is 0.2 from it: yes
])
def test_distinct_views_of_detection_by_hand(cam_ys, views):
    t = detect_from(mapper_for(2), cam_ys)
    assert t.n == 1 and t.n_det[0] == len(cam_ys) and t.det_views[0] == views


@pytest.mark.parametrize("min_views, cam_ys, stays", [
    (2, (0.0, 0.0, 0.0), False),  # 3 detections, all from one view: a one-view false positive
    (2, (0.0, 0.1, 0.2), True),
    (None, (0.0, 0.0, 0.0), True),  # the rule off: 3 detections confirm it
])
def test_confirmation_needs_distinct_views(min_views, cam_ys, stays):
    mapper = mapper_for(min_views)
    t = detect_from(mapper, cam_ys)
    removed = mapper.prune_unconfirmed(2, -1, "end of session", 0.2)
    assert t.status[0] == (ACTIVE if stays else REMOVED) and removed == (0 if stays else 1)
    if not stays:
        detail = [e.detail for e in mapper.map.events if e.kind == "removed"][0]
        assert "detected from 1 distinct view, needs 2" in detail


def test_unconfirmed_by_views_by_hand():
    n_det, n_clear = np.array([3, 3, 1]), np.array([3, 3, 3])
    views = np.array([1, 2, 2])
    np.testing.assert_array_equal(unconfirmed(n_det, n_clear, 2, 0.2, views, 2), [True, False, True])
    np.testing.assert_array_equal(unconfirmed(n_det, n_clear, 2, 0.2, views, None), [False, False, True])
    # 0 views: an object made before views were counted (a map of an older ltc, its session resumed).
    np.testing.assert_array_equal(unconfirmed(np.array([3]), np.array([3]), 2, 0.2, np.array([0]), 2), [False])

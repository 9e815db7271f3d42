"""maintenance.confirm_across_views (issue 9, thirty-fifth round): a thing detected often enough in
each of two sessions, but from one view in each, is confirmed when the two sessions' views lie
apart. Expected values by hand."""

import numpy as np
import pytest

from ltc_cli import plugins
from ltc_cli.config import defaults
from ltc_cli.map.model import ACTIVE, REMOVED, SemanticMap
from ltc_cli.pipeline.mapper import Mapper
from ltc_cli.pipeline.views import views_apart, widen_span
from tests.scene import INTR, T_world_camera, render
from tests.test_identity import CHAIR_FACE, CLASSES, chair_vector


def span(x=0.0, y=0.0, turn_deg=0.0):
    """The span of one view: the camera at (x, y, 1) looking along +x turned ``turn_deg`` about z."""
    a = np.radians(turn_deg)
    return widen_span(np.zeros(20), np.array([x, y, 1.0, np.cos(a), np.sin(a), 0.0]), True)


def test_views_apart_by_hand():
    """0.15 m or 10 degrees apart (the defaults) along one of the span's directions: 0.1 m is not,
    0.2 m along x is; 15 degrees turn the forward axis by sin 15 = 0.26 along y, over the chord of
    10 degrees (2 sin 5 = 0.17); 5 degrees move it by at most 0.09 along y and 0.06 along the
    diagonals."""
    a = np.stack([span(), span(), span(), span()])
    b = np.stack([span(x=0.1), span(x=0.2), span(turn_deg=15), span(turn_deg=5)])
    assert views_apart(a, b, 0.15, 10).tolist() == [False, True, True, False]
    # 0.1 m along both x and y is 0.14 m along a diagonal: still one view.
    assert views_apart(span()[None], span(x=0.1, y=0.1)[None], 0.15, 10).tolist() == [False]
    assert views_apart(span()[None], span(x=0.1, y=0.1)[None], 0.1, None).tolist() == [True]


def two_detection_session(smap, cfg, session: int, cam_y: float, frames: int = 2):
    """One session whose ``frames`` frames, all from the camera at y = ``cam_y``, detect the chair
    face, then the session's end. Returns how many objects it removed."""
    mapper = Mapper(smap, cfg, plugins.get("metrics", "vertex").factory(cfg["association"]),
                    plugins.get("policies", "non-detection").factory(cfg["maintenance"]), session=session)
    seen, masks = render([CHAIR_FACE], wall_x=4.0, cam_y=cam_y)
    for k in range(frames):
        mapper.process_frame(k, f"{session}-{k}", [masks[0]], [chair_vector(0.8)], seen,
                             T_world_camera(cam_y=cam_y), INTR, (0.3, 6.0))
    m = cfg["maintenance"]
    return mapper.prune_unconfirmed(m["min_detections"], -1, "end", m["min_detection_share"])


@pytest.mark.parametrize("rule, cam_y, frames, stays", [
    (True, 0.3, 2, True),  # 0.3 m from session 0's view: two views
    (False, 0.3, 2, False),  # each session confirms alone
    (True, 0.05, 2, False),  # the same view again: a false positive recurs from one view
    (True, 0.3, 1, False),  # one detection: too few, whatever the views
])
def test_two_sessions_from_two_views_confirm(rule, cam_y, frames, stays):
    """Session 0 detects the chair twice from one view: removed as unconfirmed at its end (one
    distinct view, needs 2). Session 1 detects it ``frames`` times from a camera ``cam_y`` m to the
    side: it stays (logged as confirmed by object 1) only when the rule is on, it had enough
    detections and the two sessions' views are apart."""
    cfg = defaults()
    cfg["maintenance"]["confirm_across_sessions"] = False
    cfg["maintenance"]["confirm_across_views"] = rule
    smap = SemanticMap.new(CLASSES)
    t = smap.objects
    assert two_detection_session(smap, cfg, 0, 0.0) == 1
    assert t.n == 1 and t.status[0] == REMOVED and t.n_det[0] == 2
    removed = two_detection_session(smap, cfg, 1, cam_y, frames)
    assert t.n == 2 and t.first_session[1] == 1
    assert removed == (0 if stays else 1)
    assert t.status[1] == (ACTIVE if stays else REMOVED)
    confirmed = [e for e in smap.events if e.kind == "updated" and str(e.detail).startswith("confirmed: object 1")]
    assert len(confirmed) == (1 if stays else 0)

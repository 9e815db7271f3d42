"""maintenance.confirm_across_sessions (issue 9, twenty-fourth round): a thing the detector names
once per visit is confirmed by a second visit that names it at the same place. Expected values by
hand."""

import numpy as np
import pytest

from ltc_cli import plugins
from ltc_cli.config import defaults
from ltc_cli.geometry.boxes import Boxes
from ltc_cli.map.model import ACTIVE, MERGED, REMOVED, SemanticMap
from ltc_cli.pipeline.maintenance import removed_unconfirmed
from ltc_cli.pipeline.rejoining import same_class_overlap
from ltc_cli.pipeline.mapper import Mapper
from tests.scene import INTR, T_world_camera, render
from tests.test_identity import CHAIR_FACE, CLASSES, chair_vector


def boxes(*rows):
    """Boxes from (x, y, side) rows: side x side x 0.5 m, yaw 0."""
    return Boxes(np.array([[x, y, 0.25] for x, y, _ in rows], dtype=float), np.zeros(len(rows)),
                 np.array([[s, s, 0.5] for _, _, s in rows], dtype=float), np.zeros((len(rows), 8), bool))


def test_removed_unconfirmed_by_hand():
    """Session 3: rows 0-1 qualify (removed, detected only in session 1 or 2, weak); row 2 was
    detected in two sessions, row 3 is active, row 4 was made in this session, row 5 merged, row 6
    had strong evidence (removed for another reason)."""
    status = np.array([REMOVED, REMOVED, REMOVED, ACTIVE, REMOVED, MERGED, REMOVED])
    first = np.array([1, 2, 1, 1, 3, 1, 1])
    last = np.array([1, 2, 2, 1, 3, 1, 1])
    weak = np.array([True, True, True, True, True, True, False])
    assert removed_unconfirmed(status, first, last, weak, 3, REMOVED).tolist() == \
        [True, True, False, False, False, False, False]


def test_same_class_overlap_by_hand():
    """Tentative 1 x 1 m boxes at x 0, 5 and 10; earlier ones: at x 0.8 (class 0, overlaps the
    first by 0.2 x 1 = 0.2, IoU 0.2 / 1.8), at x 0.5 (class 1: another class), at x 5.5 (class 0,
    IoU 0.5 / 1.5), at x 6.5 (class 0, IoU 0: 0.5 m apart); the third tentative box is of class 1,
    with none of its class near it."""
    cand = boxes((0, 0, 1), (5, 0, 1), (10, 0, 1))
    earlier = boxes((0.8, 0, 1), (0.5, 0, 1), (5.5, 0, 1), (6.5, 0, 1))
    out = same_class_overlap(cand, np.array([0, 0, 1]), earlier, np.array([0, 1, 0, 0]))
    assert out.tolist() == [0, 2, -1]
    # The best overlap wins: a second class-0 box at x 0.3 (IoU 0.7 / 1.3) beats x 0.8.
    earlier = boxes((0.8, 0, 1), (0.3, 0, 1))
    assert same_class_overlap(cand, np.array([0, 0, 1]), earlier, np.array([0, 0])).tolist() == [1, -1, -1]
    assert same_class_overlap(cand, np.array([0, 0, 1]), boxes(), np.zeros(0, int)).tolist() == [-1, -1, -1]


def one_detection_session(smap, cfg, session: int):
    """One session of one frame that detects the chair face, then the session's end."""
    mapper = Mapper(smap, cfg, plugins.get("metrics", "vertex").factory(cfg["association"]),
                    plugins.get("policies", "non-detection").factory(cfg["maintenance"]), session=session)
    seen, masks = render([CHAIR_FACE], wall_x=4.0)
    mapper.process_frame(0, f"{session}-0", [masks[0]], [chair_vector(0.8)], seen, T_world_camera(), INTR,
                         (0.3, 6.0))
    m = cfg["maintenance"]
    removed = mapper.prune_unconfirmed(m["min_detections"], -1, "end", m["min_detection_share"])
    return mapper, removed


@pytest.mark.parametrize("rule", [True, False])
def test_a_chair_named_once_in_each_of_two_sessions_stays(rule):
    """Session 0 detects the chair once: removed as unconfirmed at its end (1 detection, needs 2).
    Session 1 detects it once more at the same place: it stays with the rule (logged as confirmed by
    object 1), and goes again without it."""
    cfg = defaults()
    cfg["maintenance"]["confirm_across_sessions"] = rule
    smap = SemanticMap.new(CLASSES)
    _, removed = one_detection_session(smap, cfg, 0)
    t = smap.objects
    assert removed == 1 and t.n == 1 and t.status[0] == REMOVED
    mapper, removed = one_detection_session(smap, cfg, 1)
    assert t.n == 2 and t.first_session[1] == 1  # a new object: the removed one is not revived
    if not rule:
        assert removed == 1 and t.status[1] == REMOVED
        return
    assert removed == 0 and t.status[1] == ACTIVE
    assert any(e.kind == "updated" and e.object_id == 2 and str(e.detail).startswith("confirmed: object 1")
               for e in smap.events)
    # A third session that names it once more: it is an earlier session's confirmed object now.
    _, removed = one_detection_session(smap, cfg, 2)
    assert removed == 0 and t.n == 2 and t.status[1] == ACTIVE


@pytest.mark.parametrize("beside, stays", [(False, True), (True, False)])
def test_no_confirmation_beside_the_same_thing_already_mapped(beside, stays):
    """Session 1 ends with a one-detection chair (row 1, 1 x 1 m at x 2.2) over the footprint of a
    chair session 0 removed as unconfirmed (row 0, at x 2.0): it stays, unless a chair of the map
    already stands on its footprint (row 2 at x 2.6, 20 detections): that one is the thing, and
    the candidate a duplicate of it."""
    cfg = defaults()
    cfg["maintenance"]["confirm_across_sessions"] = True
    smap = SemanticMap.new(CLASSES)
    t = smap.objects
    chair = chair_vector(0.8)

    def add(x, status, session, n_det):
        t.append(center=np.array([x, 0.0, 0.5]), yaw=0.0, size=np.array([1.0, 1.0, 1.0]), scores=chair,
                 n_det=n_det, status=status, first_session=session, last_session=session)

    add(2.0, REMOVED, 0, 1)
    add(2.2, ACTIVE, 1, 1)
    if beside:
        add(2.6, ACTIVE, 0, 20)
    mapper = Mapper(smap, cfg, plugins.get("metrics", "vertex").factory(cfg["association"]),
                    plugins.get("policies", "non-detection").factory(cfg["maintenance"]), session=1)
    assert mapper.prune_unconfirmed(2, -1, "end") == (0 if stays else 1)
    assert t.status[1] == (ACTIVE if stays else REMOVED)

"""Two small things of one class side by side are two things (association.same_class_scale), and a
Defined box shorter than any whole object of its class does not replace the box of the whole when
two map objects merge (modeling.defined_min_width, tv 0.3 m); issue 9, thirtieth round, from
tum-fr1-rpy's mouse beside a monitor's foot. Values worked out by hand."""

import numpy as np
import pytest

from ltc_cli import plugins
from ltc_cli.config import defaults
from ltc_cli.geometry.boxes import Boxes
from ltc_cli.map.model import ACTIVE, MERGED, SemanticMap
from ltc_cli.pipeline.association import size_caps, thresholds_for
from ltc_cli.pipeline.deduplication import duplicate_pairs
from ltc_cli.pipeline.mapper import Mapper

CLASSES = ["tv", "mouse", "chair"]
TV, MOUSE, CHAIR = 0, 1, 2
MOUSE_SIZE, FOOT_SIZE = [0.1, 0.06, 0.04], [0.19, 0.08, 0.13]


def test_same_class_caps_by_hand():
    # Half diagonals: the mouse sqrt(0.01 + 0.0036 + 0.0016) / 2 = 0.06164, the foot
    # sqrt(0.0361 + 0.0064 + 0.0169) / 2 = 0.12207; the cap is 1.5 x the larger: 0.18310.
    caps = size_caps(np.array(MOUSE_SIZE), np.array([FOOT_SIZE]), 1.5)
    assert caps[0] == pytest.approx(1.5 * np.sqrt(0.0594) / 2)
    # One class: min(0.4, 0.1831); another: the other-class threshold alone (no cap given).
    thr = thresholds_for(MOUSE, np.array([MOUSE, TV]), 0.4, 0.25, None, np.array([caps[0], caps[0]]))
    np.testing.assert_allclose(thr, [1.5 * np.sqrt(0.0594) / 2, 0.25])
    assert size_caps(np.array(MOUSE_SIZE), np.array([FOOT_SIZE]), None) is None


def centre_distance(one: Boxes, many: Boxes) -> np.ndarray:
    return np.linalg.norm(many.center - one.center[0], axis=1)


def pair(sizes, gap):
    c = np.array([[0.0, 0.0, 0.5], [gap, 0.0, 0.5]])
    return Boxes(c, np.zeros(2), np.asarray(sizes, float), np.ones((2, 8), bool))


@pytest.mark.parametrize("scale, merged", [(None, True), (1.5, False)])
def test_a_mouse_and_a_foot_called_mouse_side_by_side_stay_two(scale, merged):
    """0.2 m apart (centre distance stands for eq. 2): under the fixed 0.4 m they merge; the cap
    0.1831 m keeps them apart."""
    pairs = duplicate_pairs(pair([MOUSE_SIZE, FOOT_SIZE], 0.2), np.array([MOUSE, MOUSE]), centre_distance,
                            0.4, 0.25, None, None, same_scale=scale)
    assert (pairs == [(pytest.approx(0.2), 0, 1)]) if merged else (pairs == [])


def test_furniture_keeps_the_fixed_threshold():
    """Two views of one 0.5 x 0.5 x 0.9 m chair 0.3 m apart: the cap 1.5 x 0.5724 = 0.859 m does not
    bind, 0.3 < 0.4 merges them as before."""
    pairs = duplicate_pairs(pair([[0.5, 0.5, 0.9]] * 2, 0.3), np.array([CHAIR, CHAIR]), centre_distance,
                            0.4, 0.25, None, None, same_scale=1.5)
    assert pairs == [(pytest.approx(0.3), 0, 1)]


def make_mapper(cfg):
    smap = SemanticMap.new(CLASSES)
    return Mapper(smap, cfg, plugins.get("metrics", "vertex").factory(cfg["association"]),
                  plugins.get("policies", "static").factory(cfg["maintenance"]))


def add_object(mapper, center, size, cls, n_det, defined, visible=None):
    scores = np.zeros(len(CLASSES) + 1)
    scores[cls] = 1.0
    row = mapper.map.objects.append(center=center, yaw=0.0, size=size,
                                    visible=np.ones(8, bool) if visible is None else visible, defined=defined,
                                    scores=scores, n_det=n_det, n_nondet=0, status=ACTIVE)
    mapper.index.insert(row, np.asarray(center, float), np.asarray(size, float))
    return row


@pytest.mark.parametrize("scale, matched", [(None, True), (1.5, False)])
def test_a_mouse_detection_beside_the_foot_is_a_mouse_of_its_own(scale, matched):
    """Stage 2: a Defined mouse detection 0.2 m from a Defined "mouse" box on a monitor's foot
    (eq. 2 over all 8 vertices, both yaw 0 and the same height: 0.2 m plus what the sizes add,
    under 0.4, over 0.1831). ``max_union_length`` is off: it parts the two by their length alone;
    so is ``defined_min_overlap``: the two whole boxes share no ground."""
    cfg = defaults()
    cfg["association"]["same_class_scale"] = scale
    cfg["association"]["max_union_length"] = {}
    cfg["association"]["defined_min_overlap"] = None
    mapper = make_mapper(cfg)
    foot = add_object(mapper, [2.0, 0.2, 0.8], FOOT_SIZE, MOUSE, n_det=7, defined=True)
    det = Boxes(np.array([[2.0, 0.0, 0.8]]), np.zeros(1), np.array([MOUSE_SIZE]), np.ones((1, 8), bool))
    row, _ = mapper._associate(det, MOUSE, np.array([foot]), True)
    assert row == (foot if matched else -1)


@pytest.mark.parametrize("widths, replaced", [({}, True), ({"tv": 0.3}, False)])
def test_a_short_defined_piece_of_a_monitor_does_not_replace_its_box_in_a_merge(widths, replaced):
    """A partial tv box 0.55 x 0.2 x 0.4 m (9 detections; its far end's four corners unseen) and a
    Defined one 0.24 x 0.11 x 0.35 inside it (2 detections) merge. The paper's rule (i Defined, j
    partial) gives the 0.24 m box; held to a tv's 0.3 m whole width, the short one is a part: the
    two enclose, which is the partial box (the erosion never shrinks it below the larger one)."""
    cfg = defaults()
    cfg["modeling"]["defined_min_width"] = widths
    cfg["integration"]["defined_part_volume"] = None
    mapper = make_mapper(cfg)
    seen = np.array([True, False, False, True, True, False, False, True])
    whole = add_object(mapper, [0.5, 1.45, 1.0], [0.55, 0.2, 0.4], TV, n_det=9, defined=False, visible=seen)
    piece = add_object(mapper, [0.5, 1.42, 1.0], [0.24, 0.11, 0.35], TV, n_det=2, defined=True)
    mapper._absorb(whole, piece, 1, "1")
    t = mapper.map.objects
    assert t.status[piece] == MERGED
    if replaced:
        np.testing.assert_allclose(t.size[whole], [0.24, 0.11, 0.35])
    else:
        np.testing.assert_allclose(sorted(t.size[whole][:2]), [0.2, 0.55])
        assert t.size[whole][2] == pytest.approx(0.4)
        np.testing.assert_allclose(t.center[whole], [0.5, 1.45, 1.0], atol=1e-9)

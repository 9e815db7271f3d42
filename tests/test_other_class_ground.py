"""association.other_class_min_overlap (issue 9, twentieth round): a detection matches a map object
of another top class only when they share at least that much of the smaller footprint. One object
under two labels stands on its own ground; a "mouse" beside a stack of papers (on tum-fr1-rpy, a
monitor's foot the detector calls so) does not. Values worked out by hand."""

import numpy as np
import pytest

from ltc_cli import plugins
from ltc_cli.config import load_config
from ltc_cli.geometry.boxes import Boxes
from ltc_cli.map.model import ACTIVE, SemanticMap
from ltc_cli.pipeline.association import apart_grounds, ground_shares
from ltc_cli.pipeline.mapper import Mapper

CLASSES = ["book", "mouse"]  # then other
# A Defined 0.46 x 0.37 x 0.06 m stack of papers called book: footprint x in [-0.23, 0.23],
# y in [-0.185, 0.185], z in [0.76, 0.82].
BOOK = ([0.0, 0.0, 0.79], 0.0, [0.46, 0.37, 0.06])
# A 0.12 x 0.10 x 0.07 m mouse beside its corner: x in [-0.33, -0.21], y in [-0.245, -0.145].
MOUSE = ([-0.27, -0.195, 0.795], 0.0, [0.12, 0.10, 0.07])


def box(center, yaw, size, visible=None):
    vis = np.ones((1, 8), bool) if visible is None else np.isin(np.arange(8), visible)[None]
    return Boxes(np.array([center], float), np.array([yaw], float), np.array([size], float), vis)


@pytest.mark.parametrize("a, b, share", [
    # The mouse's corner in the book: 0.02 x 0.04 = 0.0008 m^2 of its 0.012 m^2.
    (MOUSE, BOOK, 0.0008 / 0.012),
    # A 0.2 m square turned 45 degrees, centred on the book's edge x = 0.23: half of it.
    (([0.23, 0.0, 0.79], np.pi / 4, [0.2, 0.2, 0.05]), BOOK, 0.5),
    (([0.1, 0.05, 0.79], 0.3, [0.1, 0.1, 0.05]), BOOK, 1.0),   # wholly on it
    (([0.6, 0.0, 0.79], 0.0, [0.2, 0.2, 0.05]), BOOK, 0.0),    # 0.27 m away
])
def test_ground_shares_by_hand(a, b, share):
    assert ground_shares(box(*a), box(*b))[0] == pytest.approx(share, abs=1e-9)
    assert ground_shares(box(*b), box(*a))[0] == pytest.approx(share, abs=1e-9)  # either order


def test_only_judged_pairs_are_kept_apart():
    a, b = box(*MOUSE), box(*BOOK)
    assert apart_grounds(a, b, np.array([True]), 0.2).tolist() == [True]     # 0.067 < 0.2
    assert apart_grounds(a, b, np.array([False]), 0.2).tolist() == [False]   # not judged (one class, or beyond eq. 2)
    assert apart_grounds(a, b, np.array([True]), 0.05).tolist() == [False]   # 0.067 >= 0.05
    assert apart_grounds(a, b, np.array([True]), None).tolist() == [False]   # the paper
    # One detection against several candidates: only the judged ones are clipped and told apart.
    # The second candidate is a 0.2 m box centred on the mouse: the mouse wholly on it (share 1).
    cands = Boxes(np.array([BOOK[0], MOUSE[0], BOOK[0]]), np.zeros(3),
                  np.array([BOOK[2], [0.2, 0.2, 0.07], BOOK[2]]), np.ones((3, 8), bool))
    assert apart_grounds(a, cands, np.array([True, True, False]), 0.2).tolist() == [True, False, False]


def associate(det, det_class, overrides=()):
    cfg = load_config(None, list(overrides))
    smap = SemanticMap.new(CLASSES)
    row = smap.objects.append(center=np.array(BOOK[0]), yaw=0.0, size=np.array(BOOK[2]), visible=np.ones(8, bool),
                              defined=True, scores=np.array([0.9, 0.05, 0.05]), n_det=5, status=ACTIVE,
                              first_session=0, last_session=0)
    mapper = Mapper(smap, cfg, plugins.get("metrics", "vertex").factory(cfg["association"]),
                    plugins.get("policies", "non-detection").factory(cfg["maintenance"]), session=0)
    return mapper._associate(det, det_class, np.array([row]), False)[0] == row


# The mouse seen partly, its four vertices on the -x side visible (0, 3, 4, 7): by eq. 2 over those
# pairs it is (0.1166 + 0.1170 + 0.3448 + 0.3450) / 4 = 0.2309 m from the book, under the
# other-class threshold min(0.25, 1.25 x the book's 0.297 m half diagonal) = 0.25 m.
SEEN_MOUSE = box(*MOUSE, visible=[0, 3, 4, 7])


def test_eq2_alone_puts_the_mouse_on_the_papers():
    d = plugins.get("metrics", "vertex").factory(load_config(None, [])["association"]).distance
    assert d(SEEN_MOUSE, box(*BOOK))[0] == pytest.approx(0.2309, abs=1e-3)
    assert associate(SEEN_MOUSE, 1, ["association.other_class_min_overlap=null"])  # the paper


def test_a_mouse_beside_the_papers_is_another_object():
    assert not associate(SEEN_MOUSE, 1)


def test_the_papers_called_mouse_still_fuse_with_the_book():
    # A partial 0.30 x 0.25 view of the stack itself under the other label: wholly on its ground.
    assert associate(box([-0.08, -0.06, 0.79], 0.0, [0.30, 0.25, 0.06], visible=[0, 3, 4, 7]), 1)


def test_a_partial_book_beside_the_book_is_judged_by_eq2_alone():
    assert associate(SEEN_MOUSE, 0)  # its own class: the ground rule is for labels only

"""A partial view rendered beside a partial piece in the map: does it join the piece or make its
own object? Shared by tests/test_adjoin_turn.py and tests/test_adjoin_except.py."""

import numpy as np

from ltc_cli import plugins
from ltc_cli.geometry.boxes import Boxes
from ltc_cli.map.model import ACTIVE, SemanticMap
from ltc_cli.pipeline.association import footprint_gaps
from ltc_cli.pipeline.mapper import Mapper
from tests.scene import INTR, T_world_camera, render


def mapper_with_piece(cfg: dict, classes: list, center, yaw: float, size, scores) -> Mapper:
    """A mapper whose map holds one partial object (row 0), detected five times."""
    smap = SemanticMap.new(classes)
    mapper = Mapper(smap, cfg, plugins.get("metrics", "vertex").factory(cfg["association"]),
                    plugins.get("policies", "non-detection").factory(cfg["maintenance"]))
    center, size = np.asarray(center, float), np.asarray(size, float)
    row = smap.objects.append(center=center, yaw=yaw, size=size, visible=np.zeros(8, bool), defined=False,
                              scores=scores, n_det=5, n_nondet=0, status=ACTIVE)
    mapper.index.insert(row, center, size)
    return mapper


def view_beside_piece(mapper: Mapper, face: tuple, scores, joins: bool, reach_y: float) -> None:
    """Process the detection of ``face`` (x0, x1, y0, y1, z0, z1, seen from the origin along +x).
    ``joins``: the piece's box takes the view (its corners reach below y = ``reach_y``). Otherwise
    the view is a new object, the piece is unchanged, and the new box lies within
    ``partial_adjoin_gap`` of it: the rule under test, not the gap, kept them apart."""
    t = mapper.map.objects
    piece = t.boxes(np.array([0]))
    depth, masks = render([face], wall_x=4.0)
    res = mapper.process_frame(1, "f1", masks, [scores], depth, T_world_camera(), INTR, (0.3, 6.0))
    if joins:
        assert (res.created, res.matched) == (0, 1)
        assert t.boxes(np.array([0])).corners[0][:, 1].min() < reach_y
        return
    assert (res.created, res.matched) == (1, 0)
    np.testing.assert_allclose(t.center[0], piece.center[0])
    np.testing.assert_allclose(t.size[0], piece.size[0])
    gap = footprint_gaps(t.boxes(np.array([1])), Boxes(piece.center, piece.yaw, piece.size, piece.visible))[0]
    assert 0.0 <= gap <= mapper.cfg["association"]["partial_adjoin_gap"]

"""Two partial pieces of one long object already in the map merge (association.merge_adjoining,
issue 9 twenty-third round: held-out house 201 kept three boxes for one dining table)."""

import numpy as np

from ltc_cli import plugins
from ltc_cli.config import defaults, load_config
from ltc_cli.geometry.boxes import Box, Boxes
from ltc_cli.map.model import ACTIVE, MERGED, SemanticMap
from ltc_cli.pipeline.deduplication import adjoining_part_pairs, enclosed_part, merge_pairs
from ltc_cli.pipeline.mapper import Mapper
from tests.scene import INTR, T_world_camera, render

TABLE, CHAIR = 0, 1
SHARE = np.array([0.1, 0.0, 0.0])  # dining table 0.1, chair none, other none

# Footprints (x range; all y -0.3..0.3) and z ranges, axis-aligned, worked out by hand:
# 0 partial table  x -0.50..0.50  z 0..0.8   longer side 1.0: a gap of max(0.05, 0.1 x 1.0) = 0.1 joins
# 1 partial table  x  0.58..1.18  z 0..0.8   0.08 from 0
# 2 partial table  x  1.30..1.90  z 0..0.8   0.12 from 1 (longer side 0.6 x 0.1 = 0.06 < 0.12), 0.8 from 0
# 3 partial chair  x -1.08..-0.58 z 0..0.8   0.08 from 0, another class
# 4 Defined table  x -0.50..0.50  z 1.0..1.8 above 0, z apart
# Footprint areas: 0 and 4 0.6 m2, 1 and 2 0.36 m2, 3 0.3 m2.
CENTER = [[0, 0, 0.4], [0.88, 0, 0.4], [1.6, 0, 0.4], [-0.83, 0, 0.4], [0, 0, 1.4]]
SIZE = [[1.0, 0.6, 0.8], [0.6, 0.6, 0.8], [0.6, 0.6, 0.8], [0.5, 0.6, 0.8], [1.0, 0.6, 0.8]]
TOP = np.array([TABLE, TABLE, TABLE, CHAIR, TABLE])


def scene(n=5) -> Boxes:
    return Boxes(np.array(CENTER[:n], float), np.zeros(n), np.array(SIZE[:n], float), np.ones((n, 8), bool))


def test_adjoining_part_pairs_by_hand():
    defined = np.array([False, False, False, False, True])
    pairs = adjoining_part_pairs(scene(), TOP, defined, SHARE, 0.05)
    assert [(a, b) for _, a, b in pairs] == [(0, 1)]
    assert abs(pairs[0][0] - 0.08) < 1e-9
    # A share of 0.25 of the 0.6 m sides reaches 0.15: 1 and 2 (0.12 apart) join; 0 and 2 (0.8
    # apart, 0.25 of 1.0 m) do not.
    assert [(a, b) for _, a, b in adjoining_part_pairs(scene(), TOP, defined, SHARE * 2.5, 0.05)] == [(0, 1), (1, 2)]
    # A Defined piece and a partial one are pieces too; two Defined pieces are two things.
    defined[:2] = [False, True]
    assert [(a, b) for _, a, b in adjoining_part_pairs(scene(), TOP, defined, SHARE, 0.05)] == [(0, 1)]
    defined[:2] = [True, True]
    assert adjoining_part_pairs(scene(), TOP, defined, SHARE, 0.05) == []
    assert adjoining_part_pairs(scene(), TOP, np.zeros(5, bool), None, 0.05) == []


def test_merge_pairs_takes_adjoining_pieces_by_the_settings():
    """With the defaults the pieces 0 and 1 are a merge pair (after every other rule's pairs);
    with docs/paper.yaml (merge_adjoining false, no containment) they are not."""
    boxes, defined, first = scene(2), np.zeros(2, bool), np.zeros(2, int)
    for cfg, expected in ((defaults(), [(0, 1)]), (load_config("docs/paper.yaml", []), [])):
        a_cfg = cfg["association"]
        metric = plugins.get("metrics", "vertex").factory(a_cfg)
        share = SHARE if a_cfg["merge_adjoining"] else None
        pairs = merge_pairs(boxes, TOP[:2], metric.distance, a_cfg, None, defined, first, 0, None, None, share)
        assert [(a, b) for _, a, b in pairs] == expected


def test_enclosed_part_by_hand():
    """The Defined piece is the part when its footprint is the smaller: 0.5 x 0.6 = 0.30 m2 against
    0.9 x 0.78 = 0.70 m2; against 0.5 x 0.5 = 0.25 m2 it is the whole."""
    def box(size, defined):
        return Box(np.zeros(3), 0.0, np.array(size, float), np.ones(8, bool), defined)
    end, rest, small = box((0.5, 0.6, 0.75), True), box((0.9, 0.78, 0.75), False), box((0.5, 0.5, 0.75), False)
    assert enclosed_part(end, rest) and enclosed_part(rest, end)
    assert not enclosed_part(end, small)


# A table seen from its end: a Defined end piece x 2.0..2.6, y -0.2..0.3 (0.30 m2) and a partial box
# of the rest x 2.0..2.9, y 0.32..1.1 (0.70 m2), 2 cm apart (under 0.1 x 0.9 m), z 0..0.75, both in
# view of the camera at the origin looking along +x (32.6 degrees each side; the far corner 29).
END = ([2.3, 0.05, 0.375], [0.6, 0.5, 0.75], True)
REST = ([2.45, 0.71, 0.375], [0.9, 0.78, 0.75], False)


def two_object_mapper(cfg, classes, scores, objects):
    """(object table, rows, mapper at session 0) of a map holding ``objects`` ((centre, size,
    Defined) each, axis-aligned, 10 detections, session 0) with the class vector ``scores``."""
    smap = SemanticMap.new(classes)
    t = smap.objects
    rows = [t.append(center=c, yaw=0.0, size=s, visible=np.ones(8, bool), defined=d, scores=np.array(scores),
                     n_det=10, status=ACTIVE, first_session=0, last_session=0) for c, s, d in objects]
    mapper = Mapper(smap, cfg, plugins.get("metrics", "vertex").factory(cfg["association"]),
                    plugins.get("policies", "non-detection").factory(cfg["maintenance"]), session=0)
    for r in rows:
        mapper.index.insert(r, t.center[r], t.size[r])
    return t, rows, mapper


def test_a_table_end_and_the_rest_enclose():
    """With merge_adjoining the two become one object whose box encloses both (the Defined end is
    the smaller piece: a part, not the whole); without it they stay two."""
    for flag, active in ((True, 1), (False, 2)):
        cfg = defaults()
        cfg["association"]["merge_adjoining"] = flag
        t, rows, mapper = two_object_mapper(cfg, ["dining table", "chair"], [0.9, 0.1, 0.0], (END, REST))
        depth, _ = render([(2.0, 2.6, -0.2, 0.3, 0.0, 0.75), (2.0, 2.9, 0.32, 1.1, 0.0, 0.75)], wall_x=4.0)
        mapper.process_frame(0, "0", [], [], depth, T_world_camera(), INTR, (0.3, 6.0))
        assert int((t.status[rows] == ACTIVE).sum()) == active
        if flag:
            # The older id stays; its box encloses both: x 2.0..2.9 (the larger piece's 0.9 m), y
            # -0.2..1.1 less the erosion per side, z 0..0.75.
            assert t.status[rows[1]] == MERGED
            erosion = cfg["integration"]["erosion"]
            np.testing.assert_allclose(t.size[rows[0]], [0.9, 1.3 - 2 * erosion, 0.75], atol=1e-6)
            np.testing.assert_allclose(t.center[rows[0]], [2.45, 0.45, 0.375], atol=1e-6)


def test_a_short_defined_end_of_a_bed_joins_the_bed():
    """modeling.defined_min_width (bed 1.5 m) holds for map objects too: a Defined 0.5 x 1.2 m box
    that its class evidence calls "bed" now (built as the "couch" end of a bed, judged whole under
    that label by stage 1) is a part of a bed, so it joins the Defined 2.0 x 1.6 m bed it overlaps
    by 0.1 m as another piece (bed's adjoin share 0.1 x 2.0 m reaches 0.2 m). By eq. 2 the two are
    far apart (centres 1.15 m), neither holds 0.3 of the other, and two Defined pieces were two
    things; with defined_min_width {} (the paper) they still are. Realistic medium house 104 kept
    such a second bed box beside its bed."""
    for min_width, active in (({"bed": 1.5}, 1), ({}, 2)):
        cfg = defaults()
        cfg["modeling"]["defined_min_width"] = min_width
        t, rows, mapper = two_object_mapper(cfg, ["bed", "chair"], [0.9, 0.0, 0.1],
                                            (([3.4, 0.0, 0.3], [2.0, 1.6, 0.6], True),
                                             ([2.25, 0.0, 0.3], [0.5, 1.2, 0.6], True)))
        depth, _ = render([(2.0, 4.4, -0.8, 0.8, 0.0, 0.6)], wall_x=6.0)
        mapper.process_frame(0, "0", [], [], depth, T_world_camera(), INTR, (0.3, 6.0))
        assert int((t.status[rows] == ACTIVE).sum()) == active
        if active == 1:
            assert t.status[rows[0]] == ACTIVE and t.status[rows[1]] == MERGED  # the bed keeps its id

"""The error breakdown (ltc_cli/tools/breakdown.py) on a hand-built map whose every error's cause is
known by construction."""

from ltc_cli.tools.breakdown import false_positive_causes, id_change_causes, missed_causes, tally
from ltc_cli.tools.evaluate import evaluate


def obj(i, cls, x, sx, sy=None, seen=None):
    o = {"id": i, "class": cls, "center": [x, 0.0, 0.5], "yaw": 0.0, "size": [sx, sy or sx, 1.0]}
    if seen is not None:
        o["seen_pixels"] = seen
    return o


GT = [obj(1, "chair", 0.0, 0.5, seen=900), obj(2, "dining table", 3.0, 1.5, 0.8, seen=900),
      obj(3, "cup", 6.0, 0.1, seen=40), obj(4, "potted plant", 9.0, 0.4, seen=500),
      obj(5, "bowl", 15.0, 0.2, seen=0)]
EARLIER = [obj(6, "sink", 12.0, 0.6)]  # there in the lap before, gone now
MAP = [obj(11, "chair", 0.02, 0.5),  # TP on the chair
       obj(12, "chair", 0.3, 0.5),  # a second box on the chair: duplicate
       obj(13, "tv", 20.0, 0.6, 0.05),  # on the poster: phantom
       obj(14, "bottle", 9.0, 0.3),  # on the plant, wrong class: mislabel
       # 0.5 x 0.8 of the table's 1.5 x 0.8 overlap: XY IoU 0.4 / 2.0 = 0.2 <= 0.25
       obj(15, "dining table", 4.0, 1.5, 0.8),
       obj(16, "couch", 30.0, 1.0),  # nothing there
       obj(17, "sink", 12.0, 0.6)]  # where the sink stood: ghost
POSTER = [obj(30000, "tv", 20.1, 0.01, 0.7)]


def test_false_positives_by_cause():
    res = evaluate(MAP, GT, previous_gt=[EARLIER])
    causes = false_positive_causes(res, MAP, GT, POSTER)
    assert causes == {12: "duplicate", 13: "phantom", 14: "mislabel", 15: "misplaced", 16: "other", 17: "ghost"}
    assert tally(causes, ("phantom", "other", "x"))["x"] == 0
    # A second table box on the table, over a pile of clutter (a phantom) on it: a duplicate of the
    # table, not a phantom (an object of its class stands there).
    clutter = [obj(30001, "book", 2.2, 0.3)]
    second = MAP + [obj(18, "dining table", 2.2, 0.4)]  # XY IoU 0.06 / 1.3 with the table
    res = evaluate(second, GT, previous_gt=[EARLIER])
    assert false_positive_causes(res, second, GT, clutter)[18] == "duplicate"


def test_missed_objects_by_cause():
    res = evaluate(MAP, GT, previous_gt=[EARLIER])
    seen = {1, 2, 3, 4}  # the bowl was never seen: not a cause of anything
    assert missed_causes(res, MAP, GT, seen) == {2: "loose", 3: "never", 4: "mislabel"}
    removed_cup = [obj(21, "cup", 6.01, 0.1)]
    assert missed_causes(res, MAP, GT, seen, removed_eq4=removed_cup)[3] == "deleted_eq4"
    assert missed_causes(res, MAP, GT, seen, removed_absent=removed_cup)[3] == "deleted_absent"
    assert missed_causes(res, MAP, GT, seen, removed_unconfirmed=removed_cup)[3] == "unconfirmed"
    assert missed_causes(res, MAP, GT, seen, removed_picture=removed_cup)[3] == "deleted_picture"
    # One chair box over two chairs: the second chair is "merged".
    two = GT + [obj(7, "chair", 0.45, 0.5, seen=900)]
    wide = [obj(11, "chair", 0.2, 1.0)]
    res2 = evaluate(wide, two)
    assert missed_causes(res2, wide, two, {1, 7})[7 if res2["matches"][0]["gt_id"] == 1 else 1] == "merged"


def test_lost_ids_by_cause():
    before = {"matches": [{"gt_id": 1, "map_id": 1}, {"gt_id": 2, "map_id": 5}, {"gt_id": 3, "map_id": 6},
                          {"gt_id": 4, "map_id": 7}]}
    after = {"matches": [{"gt_id": 1, "map_id": 8}, {"gt_id": 3, "map_id": 9}, {"gt_id": 4, "map_id": 3}]}
    status = {1: "removed", 5: "active", 6: "merged", 7: "active"}.get
    assert id_change_causes(before, after, status, [1, 2, 3, 4]) == {
        1: "removed", 2: "unmatched", 3: "merged", 4: "rematched"}


def _square(i, x, side):
    return {"id": i, "class": "cup", "center": [x, 0.0, 0.5], "yaw": 0.0, "size": [side, side, 0.1]}


def test_loose_matches_by_what_fails():
    """A 0.1 m square cup at x = 0, 10, 20, 30 and a loose box on each (XY IoU by hand):
    - 0.1 m square 0.08 m off: 0.02 x 0.1 / (0.02 - 0.002) = 0.111; moved onto the cup 1.0 -> place;
      the cup's footprint at its centre is the same box -> fails;
    - 0.4 m square on the cup's centre: 0.01 / 0.16 = 0.0625; moved: the same; the cup's footprint at
      its centre: 1.0 -> shape;
    - 0.195 m square 0.055 m off: overlap 0.0925 x 0.1, union 0.038025 + 0.01 - 0.00925 -> 0.239;
      moved: 0.01 / 0.038025 = 0.263; the cup's footprint 0.055 m off: 0.045 / 0.155 = 0.290 -> either;
    - 0.4 m square 0.2 m off: overlap 0.05 x 0.1 / (0.16 + 0.01 - 0.005) = 0.030; moved 0.0625; the
      cup's footprint 0.2 m off: no overlap -> both.
    A fifth box, 0.1 m square 0.01 m off (IoU 0.09 / 0.11 = 0.818), is no loose match."""
    from ltc_cli.tools.breakdown import loose_causes

    gt = [_square(1, 0.0, 0.1), _square(2, 10.0, 0.1), _square(3, 20.0, 0.1), _square(4, 30.0, 0.1),
          _square(5, 40.0, 0.1)]
    boxes = [_square(11, 0.08, 0.1), _square(12, 10.0, 0.4), _square(13, 20.055, 0.195), _square(14, 30.2, 0.4),
             _square(15, 40.01, 0.1)]
    res = evaluate(boxes, {"objects": gt})
    assert {(m["map_id"], m["gt_id"]) for m in res["matches"]} == {(11, 1), (12, 2), (13, 3), (14, 4), (15, 5)}
    assert loose_causes(res, boxes, gt) == {1: "place", 2: "shape", 3: "either", 4: "both"}

"""Maps built directly through the library (no ingest) for the query, export and render tests."""

from __future__ import annotations

import numpy as np

from ltc_cli.map.model import ACTIVE, MERGED, REMOVED, Event, ObjectTable, SemanticMap

SESSION = {"started": "2026-01-01T10:00:00+00:00", "finished": "2026-01-01T10:05:00+00:00",
           "status": "complete", "sources": '["/data/lap1"]', "recordings": '["lap1"]', "readers": '["ltc-recording"]',
           "detector": '{"name": "recorded", "options": {}}', "metric": "vertex", "policy": "non-detection",
           "settings": "{}", "v_other": 0.5, "ltc_version": "0.1.0", "frames_done": 40, "frames_skipped": 1,
           "up_rotation": "[]"}


def _scores(n_classes, top, p):
    """A class vector (C+1,) with p on class ``top`` and the rest spread evenly (other included)."""
    v = np.full(n_classes + 1, (1.0 - p) / n_classes)
    v[top] = p
    return v


def add(smap, center, yaw, size, cls, p, status=ACTIVE, n_det=3, n_nondet=0, seen=(0, 1, 0, 9), defined=True):
    c = smap.classes.index(cls)
    row = smap.objects.append(
        center=center, yaw=yaw, size=size, visible=np.ones(8, bool), defined=defined,
        scores=_scores(len(smap.classes), c, p), n_det=n_det, n_nondet=n_nondet, status=status,
        first_session=seen[0], first_frame=seen[1], last_session=seen[2], last_frame=seen[3],
    )
    smap.events.append(Event(seen[0], seen[1], f"lap1/{seen[1]:06d}", "created", row + 1))
    return row + 1


def hand_map() -> SemanticMap:
    """8 objects over 3 classes; ids 6 and 7 removed (with logged reasons), id 8 merged into 1.

    id class  conf  center            status
    1  chair  0.80  (1, 0, 0.45)      active
    2  chair  0.55  (3, 0, 0.45)      active
    3  table  0.90  (0, 2, 0.40)      active
    4  tv     0.70  (1, 1, 2.50)      active  (high on a wall: XY-near (1,0) but 3-D far)
    5  table  0.60  (10, 10, 0.4)     active
    6  chair  0.40  (2, 2, 0.45)      removed in session 1, frame lap2/000007
    7  tv     0.45  (5, 5, 1.00)      removed in session 1, frame lap2/000012
    8  chair  0.60  (1.05, 0, 0.45)   merged
    """
    smap = SemanticMap.new(["chair", "table", "tv"])
    smap.created = "2026-01-01T10:00:00+00:00"
    smap.sessions = [dict(SESSION), dict(SESSION, sources='["/data/lap2"]', recordings='["lap2"]')]
    add(smap, [1, 0, 0.45], 0.0, [0.5, 0.5, 0.9], "chair", 0.80)
    add(smap, [3, 0, 0.45], 0.3, [0.5, 0.6, 0.9], "chair", 0.55)
    add(smap, [0, 2, 0.40], -0.2, [1.6, 0.9, 0.8], "table", 0.90)
    add(smap, [1, 1, 2.50], 0.0, [0.1, 1.2, 0.7], "tv", 0.70)
    add(smap, [10, 10, 0.40], 0.0, [1.0, 1.0, 0.8], "table", 0.60)
    add(smap, [2, 2, 0.45], 0.0, [0.5, 0.5, 0.9], "chair", 0.40, status=REMOVED, n_nondet=4, seen=(0, 3, 1, 5))
    add(smap, [5, 5, 1.00], 0.0, [0.6, 0.3, 0.4], "tv", 0.45, status=REMOVED, n_nondet=6, seen=(0, 4, 1, 9))
    add(smap, [1.05, 0, 0.45], 0.0, [0.5, 0.5, 0.9], "chair", 0.60, status=MERGED)
    smap.events += [
        Event(1, 7, "lap2/000007", "non-detection", 6),
        Event(1, 7, "lap2/000007", "removed", 6, 0, "other 0.520 > chair 0.400 after 4 non-detections and 3 detections"),
        Event(1, 12, "lap2/000012", "removed", 7, 0, "other 0.510 > tv 0.450 after 6 non-detections and 3 detections"),
        Event(0, 9, "lap1/000009", "merged", 1, 8),
    ]
    smap.frame_keys = {f"lap1/{i:06d}" for i in range(10)} | {f"lap2/{i:06d}" for i in range(13)}
    return smap


# A two-room flat, about 9 m x 6 m: (class, center, yaw, size) of the ground truth.
HOUSE = [
    ("sofa", [1.6, 4.9, 0.42], 0.0, [2.1, 0.9, 0.84]),
    ("table", [1.7, 3.3, 0.25], 0.0, [1.1, 0.6, 0.5]),
    ("tv", [1.7, 1.05, 1.1], 0.0, [1.2, 0.12, 0.7]),
    ("cabinet", [0.35, 2.6, 0.5], 0.0, [0.45, 1.2, 1.0]),
    ("chair", [3.4, 4.3, 0.45], -0.6, [0.55, 0.55, 0.9]),
    ("table", [6.6, 3.3, 0.38], 0.0, [1.6, 0.9, 0.76]),
    ("chair", [6.0, 2.55, 0.45], 0.0, [0.45, 0.45, 0.9]),
    ("chair", [7.2, 2.55, 0.45], 0.0, [0.45, 0.45, 0.9]),
    ("chair", [6.0, 4.05, 0.45], 0.0, [0.45, 0.45, 0.9]),
    ("chair", [7.2, 4.05, 0.45], 0.35, [0.45, 0.45, 0.9]),
    ("bed", [6.9, 0.0, 0.3], 0.0, [2.0, 1.6, 0.6]),
    ("cabinet", [8.7, 5.4, 0.9], 0.0, [0.6, 0.6, 1.8]),
    ("refrigerator", [4.6, 5.5, 0.9], 0.0, [0.7, 0.7, 1.8]),
    ("potted plant", [0.4, 5.6, 0.5], 0.0, [0.4, 0.4, 1.0]),
    ("chair", [3.3, 0.4, 0.45], 0.8, [0.5, 0.5, 0.9]),
]


def house_map(seed=0):
    """(map, ground-truth objects): the flat above mapped with a few cm / degrees of error, one
    chair missed (ground truth id 15) and one false positive (a tv on the bed)."""
    rng = np.random.default_rng(seed)
    classes = sorted({c for c, *_ in HOUSE})
    smap = SemanticMap.new(classes)
    smap.created = "2026-01-01T10:00:00+00:00"
    smap.sessions = [dict(SESSION)]
    gt = []
    for i, (cls, c, yaw, s) in enumerate(HOUSE):
        gt.append({"id": i + 1, "class": cls, "center": c, "yaw": yaw, "size": s})
        if i == 14:
            continue  # missed by the robot
        add(smap, np.add(c, rng.normal(0, 0.06, 3) * [1, 1, 0.2]), yaw + rng.normal(0, 0.05),
            np.multiply(s, 1 + rng.normal(0, 0.06, 3)), cls, float(rng.uniform(0.55, 0.95)))
    add(smap, [6.4, 0.2, 0.8], 0.1, [0.5, 0.3, 0.3], "tv", 0.5)
    return smap, gt


def big_map(n=100_000, seed=0):
    """n random objects of 20 classes over 200 m x 200 m; 5 % removed, with removal events."""
    rng = np.random.default_rng(seed)
    classes = [f"class{i:02d}" for i in range(20)]
    smap = SemanticMap.new(classes)
    smap.created = "2026-01-01T10:00:00+00:00"
    smap.sessions = [dict(SESSION)]
    # Fill the columns directly: appending 100,000 rows one by one would only time the test setup.
    cols = {
        "center": np.c_[rng.uniform(-100, 100, (n, 2)), rng.uniform(0.2, 1.5, n)],
        "yaw": rng.uniform(-np.pi / 2, np.pi / 2, n),
        "size": rng.uniform(0.2, 2.0, (n, 3)),
        "visible": np.ones((n, 8), bool),
        "defined": rng.random(n) < 0.7,
        "n_det": rng.integers(1, 30, n),
        "n_nondet": rng.integers(0, 5, n),
        "status": np.where(rng.random(n) < 0.05, REMOVED, ACTIVE).astype(np.int8),
        "first_session": np.zeros(n, np.int64), "first_frame": rng.integers(0, 1000, n),
        "last_session": np.zeros(n, np.int64), "last_frame": rng.integers(0, 1000, n),
    }
    scores = rng.dirichlet(np.ones(len(classes) + 1), n)
    smap.objects = ObjectTable.from_columns({**cols, "scores": scores})
    for oid in np.flatnonzero(cols["status"] == REMOVED) + 1:
        smap.events.append(Event(0, 5, "lap1/000005", "removed", int(oid), 0, "other leads"))
    return smap

"""A smaller object of another class standing under a larger one is its lower part: a monitor's foot
that the detector calls "mouse" (issue 9, tum-fr1-rpy). ltc's addition to instance de-duplication
(deduplication.py, DESIGN.md 1.2); pure numpy over boxes, applied by the mapper's merge step
(merging.py).
"""

from __future__ import annotations

import numpy as np

from ltc_cli.geometry.boxes import Boxes
from ltc_cli.geometry.polygons import convex_intersection_area


def stand_pairs(boxes: Boxes, top: np.ndarray, max_gap: float | None, margin: float = 0.05,
                min_cover: float = 0.5, established: np.ndarray | None = None,
                low: float | None = None, centred: float | None = None,
                within: float | None = None, part_of: np.ndarray | None = None,
                tentative: np.ndarray | None = None, within_floor: float = 0.0) -> list[tuple[float, int, int]]:
    """Pairs of map objects (M boxes in view, top classes (M,)) in which a smaller object of another
    class stands right under a larger one: its top within ``max_gap`` metres of the other's bottom,
    its bottom lower, and at least ``min_cover`` of its footprint under the other's footprint grown
    by ``margin`` per side. [(gap, a, b)], a < b, closest first; none when ``max_gap`` is None.

    It is the larger object's own lower part under another label: YOLOv8n calls a monitor's foot
    "mouse" (tum-fr1-rpy: the front monitor's foot, 33 detections, 4.5 cm under the screen's box).
    Separate things rest on what is under them (a cup on a table is above it); a low thing in the
    hand's breadth under a monitor's screen is its foot (but see ``low``).

    ``established`` (M,) bool: made in an earlier session; when given, such an object is never
    another's part. The map held it as a thing of its own through a whole session: on revisits of
    tum-fr1-rpy a cup of 67 detections went into a new box of the monitor behind it, and a book
    flat on the desk under a mouse's bottom (the two side by side) into the mouse.

    ``low``: when given, the smaller one is at most this share of the larger one's height. A stand
    is low (a monitor's foot plate; its neck hides behind the screen's box), a thing beside the
    screen is not: on the level tum-fr1-rpy map a mug 0.13-0.17 m tall in front of one end of a
    monitor had its top within 5 cm of the screen's bottom and went into it three times in a pass,
    while the feet the detector calls "mouse" are 0.05-0.12 m under screens of 0.37-0.38 m.

    ``centred``: when given, also a smaller object at most half the larger one's height, its top
    in the larger one's lower half (and not below its bottom by more than ``max_gap``), whose
    footprint's centre lies within this share of the larger one's length and of its width from the
    larger one's centre (in the larger one's frame), whatever ``low`` says: a foot stands under the
    middle of its screen, inside the screen's box when that box reaches down to the desk (on
    tum-fr1-rpy a front monitor's foot 0.15-0.17 m tall, 1-5 % of the screen's length and 2-22 % of
    its depth from its middle, its top 0.30-0.32 of the screen's height inside it), while a mug
    beside the screen's end stood 32-37 % of its length and 45-47 % of its depth from it.

    ``within``: when given, the smaller one's footprint centre also lies within this share of the
    larger one's length and width from its centre (0.5: inside its footprint, not only under the
    grown one). A foot stands under its screen; a mouse or a keyboard in front of a screen whose box
    grew deep does not: on tum-fr1-rpy read backwards a 0.36-0.38 m deep front monitor box took
    the keyboard in front of it (centres 0.66-0.78 of the box's depth from its middle) and the
    white mouse (0.49-0.87) as its feet, while the feet stood 0.01-0.47 of it from the middle.
    It is the share of the larger one's shorter side, and ``centred`` (when given) that of the longer,
    for both tests: the second monitor's foot stood 0.23-0.57 of its screen box's depth from its
    middle, the feet 1-5 % of their screens' length, while the white mouse under the corner of a
    front monitor box grown 0.37 m deep (tum-fr1-rpy, every third frame backwards) stood 0.49 of its
    length and 0.48 of its depth from its middle and went into it as its foot.

    ``within_floor``: metres; across the larger one's shorter side ``within`` (and ``centred``)
    allow at least this much. A monitor's foot plate reaches out in front of its screen, and a
    screen's box is thin (0.13-0.14 m on tum-fr1-rpy): with a localiser's drift the front monitor's
    foot plate stood 0.10 m in front of its screen's middle, 0.75 of the box's depth, and stayed a
    "mouse" on two revisits. The keyboard and the white mouse the share keeps apart stood 0.18-0.33
    m from the middle of a deep box.

    ``part_of``: when given, (C+1,) for each class the class its taller boxes are taken for
    (``modeling.taller_than``; -1 or NEXT: none). The smaller one of such a pair (a "mouse" under a
    "tv") may stand inside the larger one's box, its bottom up to ``max_gap`` above the larger one's
    bottom: a screen's box reaches the desk once the foot's tall views, called tv, join it, and the
    plate seen alone lies inside at the desk (tum-fr1-rpy read backwards with the int8 model: 5 mm
    above the box's bottom). Other pairs keep the bottom lower: a keyboard inside a phantom
    "suitcase" box over the desk is no stand of it.

    ``tentative`` (M,) bool: when given, such an object (made in this session and detected fewer
    than ``min_detections`` times, :func:`~ltc_cli.pipeline.maintenance.tentative`) takes no part:
    the merge keeps the larger one's label and drops the smaller one's, and one detection is no
    evidence to drop a label for (with a localiser's drift on tum-fr1-rpy's poses, a one-detection
    phantom "suitcase" over the desk took the white mouse, Defined and detected 7 times, as its foot,
    and went at the session's end as unconfirmed).
    """
    m = len(boxes)
    if max_gap is None or m < 2:
        return []
    z0 = boxes.center[:, 2] - boxes.size[:, 2] / 2
    z1 = boxes.center[:, 2] + boxes.size[:, 2] / 2
    vol = np.prod(boxes.size, axis=1)
    area = boxes.size[:, 0] * boxes.size[:, 1]
    grown = Boxes(boxes.center, boxes.yaw, boxes.size + np.array([2 * margin, 2 * margin, 0.0]),
                  np.zeros((m, 8), bool))
    height = boxes.size[:, 2]
    gap = np.abs(z0[None, :] - z1[:, None])  # [a, b]: a's top to b's bottom
    under = gap <= max_gap
    if low is not None:
        under &= height[:, None] <= low * height[None, :]
    if within is not None:
        under &= centred_under(boxes, within if centred is None else min(centred, within), within, within_floor)
    if centred is not None:
        under |= (height[:, None] <= 0.5 * height[None, :]) & (z1[:, None] >= z0[None, :] - max_gap) \
            & (z1[:, None] <= z0[None, :] + 0.5 * height[None, :]) & centred_under(boxes, centred, within, within_floor)
    lower = z0[:, None] < z0[None, :]
    if part_of is not None:
        taken_for = np.asarray(part_of)[np.asarray(top)]
        lower |= (taken_for[:, None] == np.asarray(top)[None, :]) & (z0[:, None] < z0[None, :] + max_gap)
    ok = (top[:, None] != top[None, :]) & (vol[:, None] < vol[None, :]) & under & lower
    if established is not None:
        ok &= ~np.asarray(established, dtype=bool)[:, None]
    if tentative is not None:
        ok &= ~np.asarray(tentative, dtype=bool)[None, :]
    out = []
    for a, b in zip(*np.nonzero(ok)):
        cover = convex_intersection_area(boxes.corners[a:a + 1, :4, :2], grown.corners[b:b + 1, :4, :2])[0] / area[a]
        if cover >= min_cover:
            out.append((float(gap[a, b]), min(int(a), int(b)), max(int(a), int(b))))
    return sorted(out)


def centred_under(boxes: Boxes, share: float, across: float | None = None, floor: float = 0.0) -> np.ndarray:
    """(M, M) bool, [a, b]: box a's XY centre lies within ``share`` of box b's longer footprint
    side along it and within ``across`` (default ``share``) of its shorter side, or ``floor``
    metres if that is more, along that one, from b's centre in b's own axes (a foot under the
    middle of its screen's length may stand out in front of the screen)."""
    across = share if across is None else across
    d = boxes.center[:, None, :2] - boxes.center[None, :, :2]  # [a, b]: a's centre from b's
    c, s = np.cos(boxes.yaw)[None, :], np.sin(boxes.yaw)[None, :]
    along, side = np.abs(d[..., 0] * c + d[..., 1] * s), np.abs(-d[..., 0] * s + d[..., 1] * c)
    length, width = boxes.size[None, :, 0], boxes.size[None, :, 1]
    x_long = length >= width
    on_long, on_short = np.where(x_long, along, side), np.where(x_long, side, along)
    return (on_long <= share * np.maximum(length, width)) & (
        on_short <= np.maximum(across * np.minimum(length, width), floor))

"""Stage 1 for one whole frame, as a pure function: the detections of a frame (masks and class
vectors over the map's classes) -> the modeled boxes.

The mapper calls it at the start of :meth:`Mapper.process_frame`; a distributed ingest calls it on a
Dask worker and hands the result to ``process_frame(..., stage1=...)``, so the boxes are the same
whichever process made them. It needs the settings and the map's class list only, never the map.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ltc_cli.map.model import top_class
from ltc_cli.pipeline.modeling import ModeledDetections, model_detections, pixel_scale, scaled_px
from ltc_cli.pipeline.pictures import BAND_PX, GAP_PX, flat_on_wall, mask_point
from ltc_cli.types import Intrinsics


#: taller_is value of a rule whose box goes to the detection's own next most likely class.
NEXT = -2
#: The rows above a mask's top read for the background behind it (top_in_view): pixels of a 640 x
#: 480 image, past a CNN mask's bleed, scaled up with a larger image (modeling.scale_pixels).
TOP_BAND_PX = (3, 12)


@dataclass(frozen=True)
class ClassFlags:
    """What stage 1 needs to know about each class of the map (arrays (C+1,), ``other`` last).

    moving: never a map object (people, animals); grounded: stands on the floor; depth_prior: the
    typical depth of a one-view slab (NaN: none); max_height: the height a box of the class is
    never taller than (inf: none), and taller_is: the class such a box is then (-1: none;
    NEXT: the detection's own next most likely class); max_width and wider_is: the same for the
    longer side of the box's footprint; min_width and narrower_is: the longer side a Defined box
    of the class is never under (0: none) and the class such a box is then; whole_width: the
    longer side under which a box of the class is never whole (0: none); weighted: the classes
    whose mask points count for the pixels they stand for (``pixel_weights`` as a class list;
    None: as ``pixel_weights`` says for all); max_gap and higher_is: the height above the floor
    that the bottom of a box of the class never lies over (inf: none), and the class it is then;
    min_top and top_under_is: the height above the floor that its top, seen, never lies under
    (-inf: none), and the class it is then; max_depth: the shorter horizontal side a box of the
    class is never over (inf: none; None: no class has one); max_length: the same for the longer side.
    """

    moving: np.ndarray
    grounded: np.ndarray
    depth_prior: np.ndarray
    max_height: np.ndarray | None = None
    taller_is: np.ndarray | None = None
    max_width: np.ndarray | None = None
    wider_is: np.ndarray | None = None
    weighted: np.ndarray | None = None
    min_width: np.ndarray | None = None
    narrower_is: np.ndarray | None = None
    whole_width: np.ndarray | None = None
    max_gap: np.ndarray | None = None
    higher_is: np.ndarray | None = None
    min_top: np.ndarray | None = None
    top_under_is: np.ndarray | None = None
    max_depth: np.ndarray | None = None
    max_length: np.ndarray | None = None

    @classmethod
    def from_settings(cls, classes: list[str], config: dict) -> "ClassFlags":
        moving = set(config["map"].get("moving_classes") or [])
        floor = set(config["modeling"]["floor_classes"] or [])
        priors = config["modeling"]["class_depth"] or {}
        pos = {c: i for i, c in enumerate(classes)}
        def bounds(key: str, field: str, none: float = np.inf) -> tuple[np.ndarray, np.ndarray]:
            # A rule naming a class the map does not hold has nothing to act on.
            rules = {c: r for c, r in (config["modeling"].get(key) or {}).items()
                     if c in pos and (r["is"] == "next" or r["is"] in pos)}
            return (np.array([float(rules[c][field]) if c in rules else none for c in classes] + [none]),
                    np.array([-1 if c not in rules else NEXT if rules[c]["is"] == "next" else pos[rules[c]["is"]]
                              for c in classes] + [-1]))

        wholes = config["modeling"].get("defined_min_width") or {}
        deepest = config["modeling"].get("max_short_side") or {}
        longest = config["modeling"].get("max_long_side") or {}
        weights = config["modeling"]["pixel_weights"]
        weighted = np.array([c in weights for c in classes] + [False]) if isinstance(weights, list) else None
        return cls(np.array([c in moving for c in classes] + [False]),
                   np.array([c in floor for c in classes] + [False]),
                   np.array([float(priors.get(c, np.nan)) for c in classes] + [np.nan]),
                   *bounds("taller_than", "height"), *bounds("wider_than", "width"), weighted,
                   *bounds("narrower_than", "width", 0.0),
                   np.array([float(wholes.get(c, 0.0)) for c in classes] + [0.0]),
                   *bounds("higher_than", "gap"), *bounds("top_under", "height", -np.inf),
                   np.array([float(deepest.get(c, np.inf)) for c in classes] + [np.inf]) if deepest else None,
                   np.array([float(longest.get(c, np.inf)) for c in classes] + [np.inf]) if longest else None)


@dataclass
class FrameModel:
    """Stage 1 of one frame: what stages 2-4 take from the detections.

    detections: how many detections the frame gave (over the map's classes, moving ones included);
    scores: the class vectors (C+1,) of the detections kept (moving classes dropped);
    modeled: their boxes, ``modeled.source`` indexing ``scores``; seconds: the time it took;
    flat_xyz (P, 3), flat_top (P,): a map-frame point and the top class of each detection dropped as
    a picture flat on a wall (``picture_flatness``), for the map objects they fall in.
    """

    detections: int
    scores: list[np.ndarray]
    modeled: ModeledDetections
    seconds: float = 0.0
    flat_xyz: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    flat_top: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))


def in_map_classes(detections, class_mapper) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """(masks, class vectors over the map's classes) of a detector's detections; those with no
    score on any of the map's classes are dropped. ``class_mapper``: a :class:`ClassMapper`."""
    masks, vectors = [], []
    for d in detections:
        v = class_mapper(d.scores)
        if v is not None:
            masks.append(d.mask)
            vectors.append(v)
    return masks, vectors


def model_frame(masks: list[np.ndarray], scores: list[np.ndarray], depth_m: np.ndarray, T_map_camera: np.ndarray,
                intr: Intrinsics, depth_range: tuple[float, float], config: dict, flags: ClassFlags,
                floor_z: float | None = None, measured_noise: float | None = None) -> FrameModel:
    """Stage 1 of one frame: drop moving classes, then model the rest (see :func:`model_detections`).

    masks: list of (H, W) bool; scores: list of (C+1,) class vectors over the map's classes;
    T_map_camera: (4, 4) camera-to-map pose (up rotation already applied); measured_noise: the
    depth error measured on the recording (for ``modeling.depth_noise: auto``).
    """
    sensor_noise = sensor_depth_noise(config["modeling"].get("depth_noise"), measured_noise)
    detections = len(masks)
    top = np.array([int(top_class(v)) for v in scores], dtype=int)
    if flags.moving[top].any():  # people and animals are never map objects
        keep = np.flatnonzero(~flags.moving[top])
        masks, scores, top = [masks[i] for i in keep], [scores[i] for i in keep], top[keep]
    flat_xyz, flat_top = np.zeros((0, 3)), np.zeros(0, dtype=int)
    # The bands read past a mask's bleed are pixels of a 640 x 480 image too.
    px = pixel_scale(depth_m.shape, bool(config["modeling"].get("scale_pixels", False)))
    flatness = config["modeling"]["picture_flatness"]
    if flatness is not None and masks:  # posters and paintings flat on a wall are not objects
        picture_noise = config["modeling"]["picture_depth_noise"] or 0.0
        if picture_noise:  # a noisier sensor's wall is rougher: two of its excess std more
            picture_noise += 2.0 * excess_noise(sensor_noise)
        share = config["modeling"]["picture_wall_share"]
        flat = np.array([flat_on_wall(m, depth_m, intr, T_map_camera, flatness, band_px=scaled_px(BAND_PX, px),
                                      gap_px=scaled_px(GAP_PX, px), noise_per_m2=picture_noise, wall_share=share)
                         for m in masks])
        points = [mask_point(masks[i], depth_m, intr, T_map_camera) for i in np.flatnonzero(flat)]
        flat_top = np.array([t for t, p in zip(top[flat], points) if p is not None], dtype=int)
        flat_xyz = np.array([p for p in points if p is not None]).reshape(-1, 3)
        keep = np.flatnonzero(~flat)
        masks, scores, top = [masks[i] for i in keep], [scores[i] for i in keep], top[keep]
    modeled = model_detections(masks, depth_m, intr, T_map_camera, config["modeling"], depth_range,
                               grounded=flags.grounded[top], floor_z=floor_z,
                               class_depth=flags.depth_prior[top],
                               weighted=weighted_detections(flags.weighted, top),
                               max_floor_gap=None if flags.max_gap is None else flags.max_gap[top])
    ratio = config["modeling"].get("max_depth_ratio")
    if (ratio is not None or flags.max_depth is not None) and len(modeled.source):
        src = top[modeled.source]
        modeled = drop_deep_slabs(modeled, deepest_sides(flags.depth_prior[src], ratio,
                                                         None if flags.max_depth is None else flags.max_depth[src]))
    if flags.max_length is not None and len(modeled.source):
        # A 0.21 m "cup" is a mug's mask bled onto the desk behind its rim (tum-fr1-rpy).
        margin = noise_margin(modeled.boxes.center, T_map_camera, sensor_noise)
        modeled = modeled.take(np.flatnonzero(modeled.boxes.size[:, :2].max(axis=1) - margin
                                              <= flags.max_length[top[modeled.source]]))
    min_top = config["modeling"]["floor_min_top"]
    if min_top is not None and floor_z is not None and len(modeled.source):
        modeled = drop_floor_blobs(modeled, flags.grounded[top[modeled.source]], floor_z, min_top)
    scores = list(scores)
    if modeled.bottom_gap is not None and flags.max_gap is not None and np.isfinite(flags.max_gap).any() \
            and len(modeled.source):
        # A toilet stands on the floor: a "toilet" whose lowest point seen is 0.7 m up is the sink
        # in a counter that the detector scored second (the two white bowls YOLO confuses).
        scores = relabel_too_tall(scores, modeled.source, modeled.bottom_gap, flags.max_gap, flags.higher_is)
    if floor_z is not None and flags.min_top is not None and np.isfinite(flags.min_top).any() and len(modeled.source):
        now = np.array([int(top_class(scores[int(i)])) for i in modeled.source], dtype=int)
        heights, seen = seen_tops(modeled, masks, depth_m, floor_z, flags.min_top[now],
                                  (scaled_px(TOP_BAND_PX[0], px), scaled_px(TOP_BAND_PX[1], px)))
        scores = relabel_low_tops(scores, modeled.source, heights, seen, flags)
    if flags.max_height is not None and np.isfinite(flags.max_height).any() and len(modeled.source):
        heights = modeled.boxes.size[:, 2] - noise_margin(modeled.boxes.center, T_map_camera, sensor_noise)
        scores = relabel_too_tall(scores, modeled.source, heights, flags.max_height, flags.taller_is)
    longer = modeled.boxes.size[:, :2].max(axis=1) if len(modeled.source) else np.zeros(0)
    if flags.max_width is not None and np.isfinite(flags.max_width).any() and len(modeled.source):
        # A box is seen narrower than its object (a part of it), never wider: a 0.56 m wide
        # "laptop" is no laptop (tum-fr1-rpy's fourth monitor, only its top edge in view).
        widths = longer - noise_margin(modeled.boxes.center, T_map_camera, sensor_noise)
        scores = relabel_too_tall(scores, modeled.source, widths, flags.max_width, flags.wider_is)
    if flags.min_width is not None and (flags.min_width > 0).any() and len(modeled.source):
        scores = relabel_too_narrow(scores, modeled.source, longer, modeled.defined, flags.min_width,
                                    flags.narrower_is)
    if flags.whole_width is not None and (flags.whole_width > 0).any() and len(modeled.source):
        box_top = np.array([int(top_class(scores[int(i)])) for i in modeled.source], dtype=int)
        modeled.defined = not_whole(modeled.defined, longer, flags.whole_width[box_top])
    return FrameModel(detections, scores, modeled, flat_xyz=flat_xyz, flat_top=flat_top)


def weighted_detections(weighted_classes: np.ndarray | None, top: np.ndarray) -> np.ndarray | None:
    """Per detection (top classes (N,)), whether its points are pixel-weighted; None when none is
    (the unweighted clustering, no weights to carry) or when ``pixel_weights`` is not a list."""
    if weighted_classes is None or not weighted_classes[top].any():
        return None
    return weighted_classes[top]


def deepest_sides(depth_prior: np.ndarray, ratio: float | None, max_depth: np.ndarray | None) -> np.ndarray:
    """(M,) the longest shorter horizontal side a box of each detection's class may have: ``ratio``
    times its class's typical depth (``depth_prior`` (M,), NaN: none; ``ratio`` None: no bound),
    and at most ``max_depth`` (M,) (inf or None: no bound)."""
    limit = np.full(len(depth_prior), np.inf)
    if ratio is not None:
        limit = np.nan_to_num(np.asarray(depth_prior, dtype=float), nan=np.inf) * ratio
    return limit if max_depth is None else np.minimum(limit, max_depth)


def drop_deep_slabs(modeled: ModeledDetections, deepest: np.ndarray) -> ModeledDetections:
    """The modeled boxes without those whose shorter horizontal side exceeds ``deepest`` (M,), see
    :func:`deepest_sides`: a "tv" 0.88 m deep is a mask that spilled over the desk in front of the
    screen (tum-fr1-rpy), and its box would grow or move whatever object it matched; a "book" 0.84 x
    0.96 m is a mask over a far desk's papers."""
    deep = deepest < modeled.boxes.size[:, :2].min(axis=1)
    if not deep.any():
        return modeled
    return modeled.take(np.flatnonzero(~deep))


def drop_floor_blobs(modeled: ModeledDetections, grounded: np.ndarray, floor_z: float,
                     min_top: float) -> ModeledDetections:
    """The modeled boxes without those of furniture that stands on the floor (``grounded`` (M,):
    of ``floor_classes``) whose top is under ``min_top`` metres above the floor (``floor_z``, the map's
    height of it): no chair, couch, bed or table is that low, so the points are the floor a blobby
    mask bled onto, or a base that says nothing of the box. United with the object as a partial
    view, a 1.5 m "chair" slab on the floor grew a chair's box over the place of a chair that had
    gone, whose box it then took (second held-out small house 303)."""
    tops = modeled.boxes.center[:, 2] + modeled.boxes.size[:, 2] / 2 - floor_z
    low = np.asarray(grounded, dtype=bool) & (tops < min_top)
    if not low.any():
        return modeled
    return modeled.take(np.flatnonzero(~low))


def relabel_too_tall(scores: list[np.ndarray], source: np.ndarray, heights: np.ndarray, max_height: np.ndarray,
                     taller_is: np.ndarray) -> list[np.ndarray]:
    """The class vectors (C+1,) of a frame's detections, where a detection whose box is taller than
    its top class ever stands has that class's score moved to the class it then is (the same for
    widths: the longer side of the footprint against ``wider_than``).

    source (M,): each box's detection in ``scores``; heights (M,): the boxes' z extents, metres;
    max_height, taller_is (C+1,): from :class:`ClassFlags`. A box can only be seen shorter than
    its object (a partial view), never taller, so only the upper bound of a class is used. With
    NEXT the score goes to the detection's next most likely class (``other`` excluded): a 0.8 m
    "bottle" whose detector gave potted plant second is a plant; a detection with no second class
    keeps its label (nothing says what else it is).
    """
    out = list(scores)
    for k, i in enumerate(np.asarray(source, dtype=int)):
        top = int(top_class(out[i]))
        if not heights[k] > max_height[top] or taller_is[top] == -1:
            continue
        v = np.array(out[i], dtype=np.float64)
        to = int(taller_is[top])
        if to == NEXT:
            rest = v[:-1].copy()
            rest[top] = -1.0
            to = int(np.argmax(rest))
            if rest[to] <= 0:
                continue
        v[to] += v[top]
        v[top] = 0.0
        out[i] = v
    return out


def top_in_view(mask: np.ndarray, depth_m: np.ndarray, band: tuple[int, int] = TOP_BAND_PX, behind: float = 0.15,
                share: float = 0.5) -> bool:
    """Whether the top edge of a mask (H, W) is its object's top: in the ``band`` of rows above the
    mask's top in each of its columns (from band[0] to band[1] pixels up, past a CNN mask's bleed),
    at least ``share`` of the depth readings (H, W, metres; 0 = none) lie ``behind`` metres or more
    beyond the object's median depth. A mask cut by the image's top edge, by depth holes on a shiny
    door, or split along the object ends at more of the object (or at nothing), not behind it."""
    cols = np.flatnonzero(mask.any(axis=0))
    z = depth_m[mask]
    z = z[z > 0]
    if not len(cols) or not len(z):
        return False
    first = mask[:, cols].argmax(axis=0)
    rows = first[None, :] - np.arange(band[0], band[1] + 1)[:, None]  # (band rows, columns)
    inside = rows >= 0
    if not inside.any():
        return False
    d = depth_m[rows[inside], np.broadcast_to(cols, rows.shape)[inside]]
    return bool(np.mean(d > np.median(z) + behind) >= share)


def seen_tops(modeled: ModeledDetections, masks: list[np.ndarray], depth_m: np.ndarray, floor_z: float,
              min_top: np.ndarray, band: tuple[int, int] = TOP_BAND_PX) -> tuple[np.ndarray, np.ndarray]:
    """(heights of the boxes' tops above the floor (M,), whether each top was seen (M,)) for
    :func:`relabel_low_tops`. A top is seen when a top corner is visible (the Z-buffer test: not
    hidden, inside the image) and, for a box under its class's ``min_top`` (M,), when its mask ends
    against the background (:func:`top_in_view`). A mask of a refrigerator's lower half (simulated
    house 103) has a box whose top corners pass the Z-buffer test: the door above them is no nearer
    than they are."""
    boxes = modeled.boxes
    top = boxes.center[:, 2] + boxes.size[:, 2] / 2 - floor_z
    seen = boxes.visible[:, 4:].any(axis=1)
    for k in np.flatnonzero(seen & (top < min_top)):
        seen[k] = top_in_view(masks[int(modeled.source[k])], depth_m, band)
    return top, seen


def relabel_low_tops(scores: list[np.ndarray], source: np.ndarray, top: np.ndarray, seen: np.ndarray,
                     flags: ClassFlags) -> list[np.ndarray]:
    """As :func:`relabel_too_tall`, for a lower bound on where a box's top lies above the floor
    (``top`` (M,), metres), judged only where the top was ``seen`` (M,): a refrigerator stands
    taller than a counter, so a "refrigerator" whose top is seen 0.95 m up is the oven its
    detector scored second (``min_top`` and ``top_under_is`` of :class:`ClassFlags`)."""
    return relabel_too_tall(scores, source, np.where(seen, -np.asarray(top, dtype=np.float64), -np.inf),
                            -flags.min_top, flags.top_under_is)


def relabel_too_narrow(scores: list[np.ndarray], source: np.ndarray, widths: np.ndarray, defined: np.ndarray,
                       min_width: np.ndarray, narrower_is: np.ndarray) -> list[np.ndarray]:
    """As :func:`relabel_too_tall`, for a lower bound: a Defined box (all three dimensions observed)
    whose footprint's longer side ``widths`` (M,) is under its top class's ``min_width`` (C+1,) is
    of class ``narrower_is``. A partial box may be any part of its object, so only Defined ones
    are judged. A couch seats two or more (COCO's armchair is a chair): a whole "couch" under 1 m
    is not one."""
    judged = np.where(np.asarray(defined, dtype=bool), -np.asarray(widths, dtype=np.float64), -np.inf)
    return relabel_too_tall(scores, source, judged, -np.asarray(min_width, dtype=np.float64), narrower_is)


def not_whole(defined: np.ndarray, widths: np.ndarray, whole_width: np.ndarray) -> np.ndarray:
    """The Defined flags (M,) of boxes whose footprint's longer side ``widths`` (M,) is at least the
    ``whole_width`` (M,) of their class (0: any): a box shorter than any whole object of its class
    is a part of one, whatever its corners say. A bed's foot end seen through a doorway comes out
    with every corner visible, and a Defined box is never reshaped by the partial views of the
    whole bed that follow (two boxes on one bed)."""
    return np.asarray(defined, dtype=bool) & ~(np.asarray(widths, dtype=np.float64) < np.asarray(whole_width))


def most_confident(dets: list, k: int) -> list:
    """The k detections with the highest top score, in their original order."""
    top = np.argsort([-float(np.max(d.scores)) for d in dets], kind="stable")[:k]
    return [dets[i] for i in sorted(top)]


#: The depth error (std at 1 m) the size bounds hold already: they were measured on tum-fr1-rpy
#: (a Kinect v1, about 0.0019 Z^2, Khoshelham and Elberink 2012) and checked on the simulator,
#: whose sensor errs by 0.005 Z^2 (told that, with 0.0019 here, 48 houses gained 5 false positives).
BOUNDS_SENSOR_NOISE = 0.005


def sensor_depth_noise(setting, measured: float | None) -> float | None:
    """The depth error (std at 1 m) stage 1 allows for: ``modeling.depth_noise`` when it is a number
    (or null), the error measured on the recording's frames when it is ``auto`` (None, as null,
    when nothing could be measured)."""
    return measured if setting == "auto" else setting


def excess_noise(sigma_per_m2: float | None) -> float:
    """How much a sensor's depth error (std at 1 m) exceeds what the bounds hold already
    (:data:`BOUNDS_SENSOR_NOISE`); 0 for a sensor as good or better, or none given."""
    return max(0.0, float(sigma_per_m2 or 0.0) - BOUNDS_SENSOR_NOISE)


def noise_margin(centers_xyz: np.ndarray, T_map_camera: np.ndarray, sigma_per_m2: float | None) -> np.ndarray:
    """(M,) how much longer than its object a box centred at ``centers_xyz`` (M, 3, map frame) may
    be measured with a sensor noisier than the bounds' (:data:`BOUNDS_SENSOR_NOISE`): two of the
    excess standard deviation, ``2 (sigma_per_m2 - 0.005) Z^2``, at the centre's depth Z in the
    camera (T_map_camera (4, 4), camera-to-map). A box spans its points, and each end moves with
    the error along its rays: on tum-fr1-rpy with a stereo-like error of std 0.02 Z^2 the game
    controller's boxes, 0.095 m tall at the median, were 0.127 m (a "mouse" over 0.12 m is a
    monitor's foot, ``taller_than``)."""
    excess = excess_noise(sigma_per_m2)
    if not len(centers_xyz) or not excess:
        return np.zeros(len(centers_xyz))
    R, t = T_map_camera[:3, :3], T_map_camera[:3, 3]
    z_camera = (np.asarray(centers_xyz) - t) @ R[:, 2]  # the inverse pose's third row
    return 2.0 * excess * z_camera * z_camera

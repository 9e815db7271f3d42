"""The objects and boxes that :mod:`ltc_cli.tools.evaluate` compares: map or ground-truth objects
given as dicts or objects, read into :class:`EvalObject`, and the exact overlap of Z-oriented boxes
(XY IoU and VIoU, through :func:`ltc_cli.geometry.polygons.pairwise_ious_arrays`). Pure numpy."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ltc_cli.errors import LtcError
from ltc_cli.geometry.polygons import pairwise_ious_arrays


class EvaluationError(LtcError):
    """Inputs to the evaluation that cannot be compared (malformed boxes or objects)."""


# ---------------------------------------------------------------------------------------------
# Objects


@dataclass
class EvalObject:
    """One object to compare: a map object or a ground-truth object.

    ``center (3,)``, ``yaw`` (radians), ``size (3,)`` in the map frame; ``seen_pixels`` only for
    ground truth (None = unknown, treated as seen).
    """

    id: int
    cls: str
    center: np.ndarray
    yaw: float
    size: np.ndarray
    seen_pixels: int | None = None
    extra: dict = field(default_factory=dict)


_CLASS_KEYS = ("class", "cls", "class_name", "label")


def _get(obj, key, default=None):
    if isinstance(obj, Mapping):
        return obj.get(key, default)
    return getattr(obj, key, default)


def as_eval_object(obj) -> EvalObject:
    """An :class:`EvalObject` from a dict (keys id, class, center, yaw, size[, seen_pixels]) or any
    object with those attributes (the class as ``cls``, ``class_name`` or ``label``)."""
    if isinstance(obj, EvalObject):
        return obj
    cls = None
    for key in _CLASS_KEYS:
        cls = _get(obj, key)
        if cls is not None:
            break
    oid = _get(obj, "id")
    center, yaw, size = _get(obj, "center"), _get(obj, "yaw"), _get(obj, "size")
    if cls is None or oid is None or center is None or yaw is None or size is None:
        raise EvaluationError(
            f"object {obj!r:.80} lacks one of id, class, center, yaw, size"
        )
    center = np.asarray(center, dtype=np.float64).reshape(-1)
    size = np.asarray(size, dtype=np.float64).reshape(-1)
    if center.shape != (3,) or size.shape != (3,):
        raise EvaluationError(f"object {oid}: center and size must have 3 values")
    yaw = float(yaw)
    if not (np.all(np.isfinite(center)) and np.all(np.isfinite(size)) and np.isfinite(yaw)):
        raise EvaluationError(f"object {oid}: non-finite box")
    if np.any(size < 0):
        raise EvaluationError(f"object {oid}: negative size")
    seen = _get(obj, "seen_pixels")
    return EvalObject(int(oid), str(cls), center, yaw, size, None if seen is None else int(seen))


def _box_tuple(box):
    """(center (3,), yaw, size (3,)) of a box given as a dict / object / (center, yaw, size)."""
    if isinstance(box, (tuple, list)) and len(box) == 3 and np.ndim(box[1]) == 0:
        center, yaw, size = box
    else:
        center, yaw, size = _get(box, "center"), _get(box, "yaw"), _get(box, "size")
        if center is None or yaw is None or size is None:
            raise EvaluationError(f"not a box: {box!r:.80}")
    center = np.asarray(center, dtype=np.float64).reshape(3)
    size = np.asarray(size, dtype=np.float64).reshape(3)
    return center, float(yaw), size


def _box_arrays(boxes):
    """center (N, 3), yaw (N,), size (N, 3) of a sequence of boxes or an object with array fields
    (e.g. :class:`ltc_cli.geometry.Boxes`)."""
    if hasattr(boxes, "center") and hasattr(boxes, "yaw") and np.ndim(_get(boxes, "yaw")) == 1:
        return (
            np.asarray(boxes.center, dtype=np.float64).reshape(-1, 3),
            np.asarray(boxes.yaw, dtype=np.float64).reshape(-1),
            np.asarray(boxes.size, dtype=np.float64).reshape(-1, 3),
        )
    tuples = [_box_tuple(b) for b in boxes]
    if not tuples:
        return np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3))
    c, y, s = zip(*tuples)
    return np.array(c), np.array(y), np.array(s)


# ---------------------------------------------------------------------------------------------
# IoU of Z-oriented boxes


def pairwise_ious(boxes_a, boxes_b):
    """(xy_iou (M, G), viou (M, G)) of two collections of boxes.

    Each collection is a sequence of boxes (dicts / objects with center, yaw, size, or
    ``(center, yaw, size)`` tuples) or an object with array fields ``center (N, 3)``, ``yaw (N,)``,
    ``size (N, 3)`` such as :class:`ltc_cli.geometry.Boxes`.
    """
    return pairwise_ious_arrays(*_box_arrays(boxes_a), *_box_arrays(boxes_b))


def xy_iou(box_a, box_b) -> float:
    """Exact IoU of the XY footprints of two Z-oriented boxes (dicts, objects or
    ``(center (3,), yaw, size (3,))`` tuples)."""
    ca, ya, sa = _box_tuple(box_a)
    cb, yb, sb = _box_tuple(box_b)
    return float(pairwise_ious_arrays(ca, [ya], sa, cb, [yb], sb)[0][0, 0])


def volume_iou(box_a, box_b) -> float:
    """Exact 3D IoU (VIoU) of two Z-oriented boxes: footprint intersection x z overlap / union."""
    ca, ya, sa = _box_tuple(box_a)
    cb, yb, sb = _box_tuple(box_b)
    return float(pairwise_ious_arrays(ca, [ya], sa, cb, [yb], sb)[1][0, 0])

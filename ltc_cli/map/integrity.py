"""Structural checks of a map's arrays as read from its file (pure numpy, no I/O).

A damaged map (a column cut short, a dataset of the wrong shape or type, NaN where a number is
required) must be refused when it is opened, with one line saying what is wrong, and never be
written over: loading it as if it were whole would make the next commit lose what it no longer
shows (an event log cut to one row becomes the whole log). DESIGN.md section 4.
"""

from __future__ import annotations

import numpy as np

from ltc_cli.map.model import ADDED_COLUMNS, COLUMNS, STATUS_NAMES

# The datasets every map holds (beside the ``sessions`` group).
EVENT_TEXT = ("frame_key", "kind", "detail")
EVENT_INT = ("session", "frame", "object_id", "other_id")
REQUIRED = (
    ["classes", "up_rotation", "frames", "objects/id", "objects/scores"]
    + [f"objects/{name}" for name in COLUMNS if name not in ADDED_COLUMNS]
    + [f"events/{name}" for name in EVENT_INT + EVENT_TEXT]
)


def is_text(arr: np.ndarray) -> bool:
    if arr.dtype.kind in "SU":
        return True
    return arr.dtype.kind == "O" and all(isinstance(v, (bytes, str)) for v in arr.ravel())


def _kind_name(arr: np.ndarray) -> str:
    if is_text(arr):
        return "text"
    return {"b": "true/false values", "i": "integers", "u": "integers", "f": "decimal numbers"}.get(
        arr.dtype.kind, f"values of type {arr.dtype}")


def _check_numbers(name: str, arr: np.ndarray, want: str) -> str | None:
    """``want``: "f" any number, "i" integers, "b" true/false (stored as bool or 0/1 integers)."""
    allowed = {"f": "fiu", "i": "iu", "b": "biu"}[want]
    if arr.dtype.kind not in allowed:
        expected = {"f": "numbers", "i": "integers", "b": "true/false values"}[want]
        return f"{name} holds {_kind_name(arr)}, not {expected}"
    if arr.dtype.kind == "f" and arr.size and not np.isfinite(arr).all():
        return f"{name} holds values that are not finite (NaN or infinite)"
    return None


def _check_shape(name: str, arr: np.ndarray, shape: tuple) -> str | None:
    if arr.shape != shape:
        return f"{name} has shape {arr.shape}; expected {shape}"
    return None


def check_up_rotation(R: np.ndarray) -> str | None:
    if R.dtype.kind not in "fiu":
        return f"up_rotation holds {_kind_name(R)}, not numbers"
    if R.shape != (3, 3):
        return f"up_rotation has shape {R.shape}; expected a 3x3 rotation"
    R = R.astype(np.float64)
    if not np.isfinite(R).all():
        return "up_rotation holds values that are not finite (NaN or infinite)"
    if not (np.allclose(R.T @ R, np.eye(3), atol=1e-6) and np.linalg.det(R) > 0):
        return "up_rotation is not a rotation (not orthonormal with determinant 1)"
    return None


def check_map_arrays(data: dict, sessions: dict, session_kinds: dict) -> str | None:
    """What is wrong with a map's arrays, in plain words, or None when they agree.

    ``data``: dataset path (``REQUIRED``) -> array; ``sessions``: session column -> array (the
    columns the file has); ``session_kinds``: column -> "s" text, "i" integer, "f" number.
    """
    classes = data["classes"]
    if classes.ndim != 1 or not is_text(classes) or len(classes) == 0:
        return "classes is not a list of class names"
    problem = check_up_rotation(data["up_rotation"])
    if problem:
        return problem
    frames = data["frames"]
    if frames.ndim != 1 or not is_text(frames):
        return f"frames holds {_kind_name(frames)}, not frame keys (text)"
    return _check_objects(data, len(classes)) or _check_events(data) or check_sessions(sessions, session_kinds)


def _check_objects(data: dict, n_classes: int) -> str | None:
    ids = data["objects/id"]
    problem = _check_numbers("objects/id", ids, "i")
    if problem or ids.ndim != 1:
        return problem or f"objects/id has shape {ids.shape}; expected one id per object"
    n = len(ids)
    if not np.array_equal(ids, np.arange(1, n + 1)):
        return "objects/id is not the sequence 1..N (rows were lost or reordered)"
    for name, (suffix, dtype) in COLUMNS.items():
        if name in ADDED_COLUMNS and f"objects/{name}" not in data:
            continue  # a map written before the column existed
        arr = data[f"objects/{name}"]
        want = "b" if dtype is bool else ("f" if np.dtype(dtype).kind == "f" else "i")
        problem = _check_numbers(f"objects/{name}", arr, want) or _check_shape(f"objects/{name}", arr, (n,) + suffix)
        if problem:
            return problem
    status = data["objects/status"]
    if n and not np.isin(status, list(STATUS_NAMES)).all():
        return f"objects/status holds values other than {sorted(STATUS_NAMES)}"
    scores = data["objects/scores"]
    return (_check_numbers("objects/scores", scores, "f")
            or _check_shape("objects/scores", scores, (n, n_classes + 1)))


def _check_columns(group: str, columns: dict, kinds: dict) -> str | None:
    """Columns of one table (events, sessions): 1-D, of their kind, all of one length."""
    lengths = {}
    for name, arr in columns.items():
        if arr.ndim != 1:
            return f"{group}/{name} has shape {arr.shape}; expected one value per row"
        if kinds[name] == "s":
            if not is_text(arr):
                return f"{group}/{name} holds {_kind_name(arr)}, not text"
        else:
            problem = _check_numbers(f"{group}/{name}", arr, kinds[name])
            if problem:
                return problem
        lengths[name] = len(arr)
    if len(set(lengths.values())) > 1:
        values = list(lengths.values())
        common = max(set(values), key=values.count)
        odd = ", ".join(f"{group}/{k} has {v}" for k, v in lengths.items() if v != common)
        return f"the {group} columns have different lengths ({odd}, the others {common} rows)"
    return None


def _check_events(data: dict) -> str | None:
    cols = {k: data[f"events/{k}"] for k in EVENT_INT + EVENT_TEXT}
    kinds = {k: ("i" if k in EVENT_INT else "s") for k in cols}
    return _check_columns("events", cols, kinds)


def check_sessions(sessions: dict, session_kinds: dict) -> str | None:
    """What is wrong with the session columns (column -> array, as the file has them), or None."""
    return _check_columns("sessions", sessions, session_kinds)

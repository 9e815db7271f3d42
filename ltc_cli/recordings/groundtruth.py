"""Ground truth files and the evaluation of a map against them (glue over evaluation.py)."""

from __future__ import annotations

import json
from pathlib import Path

from ltc_cli.errors import RecordingError
from ltc_cli.validation import validate


def read_ground_truth(path) -> dict:
    """The validated ground_truth.json document (ltc-ground-truth/1), given the file or a recording
    folder holding one. Raises RecordingError / SchemaError naming the file."""
    p = Path(path)
    if p.is_dir():
        p = p / "ground_truth.json"
        if not p.is_file():
            raise RecordingError("no ground_truth.json in this recording folder", path)
    elif not p.is_file():
        raise RecordingError("ground truth file does not exist", p)
    try:
        doc = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise RecordingError(f"not valid JSON ({exc})", p) from None
    validate(doc, "ground_truth", p)
    doc["_path"] = str(p)
    return doc


def previous_lap(path) -> dict | None:
    """The ground truth of the lap before, for a ``.../lapN`` recording (as ltc simulate writes
    them) whose ``lap(N-1)`` sibling exists; else None."""
    p = Path(path)
    folder = p if p.is_dir() else p.parent
    name = folder.name
    if name.startswith("lap") and name[3:].isdigit() and int(name[3:]) > 1:
        prev = folder.parent / f"lap{int(name[3:]) - 1}"
        if (prev / "ground_truth.json").is_file():
            return read_ground_truth(prev)
    return None




def earlier_laps(path) -> list[dict]:
    """The ground truth of every earlier lap of a ``.../lapN`` recording (as ltc simulate writes
    them): the ``lap1`` .. ``lap(N-1)`` siblings that hold a ground_truth.json, oldest first; [] for
    any other folder."""
    p = Path(path)
    folder = p if p.is_dir() else p.parent
    name = folder.name
    if not (name.startswith("lap") and name[3:].isdigit()):
        return []
    laps = []
    for k in range(1, int(name[3:])):
        sibling = folder.parent / f"lap{k}"
        if (sibling / "ground_truth.json").is_file():
            laps.append(read_ground_truth(sibling))
    return laps

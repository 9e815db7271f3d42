"""How right a change report is, against the simulator's list of what it moved, removed and added
between two laps (ground_truth.json ``changes``, with the objects of both laps).

Two measures:

- **by change**: a reported change is right when a true change of the same kind and class matches
  it: its place within ``tolerance`` metres (XY) of the true one's (for a move, both the old and the
  new place). Precision = right reports / reports; recall = true changes reported / true changes.
- **by place**: every change is split into what appeared somewhere (added, or moved to) and what
  disappeared from somewhere (removed, or moved from), and these are matched by class and place. A
  move reported as a removal plus an addition, or a move paired with the wrong chair, is then still
  right where the report says something happened.

Matching is one-to-one, nearest first. A ratio of 0/0 is None.
"""

from __future__ import annotations

import numpy as np

from ltc_cli.map.changes import ChangeReport


def _xy(v) -> np.ndarray:
    return np.asarray(v, dtype=np.float64)[:2]


def truth_changes(gt_before: dict, gt_after: dict) -> list[dict]:
    """[{kind, class, at (2,), from (2,) or None}] from two laps' ground-truth documents."""
    before = {o["id"]: o for o in gt_before["objects"]}
    after = {o["id"]: o for o in gt_after["objects"]}
    ch = gt_after.get("changes") or {}
    out = [{"kind": "moved", "class": after[i]["class"], "at": _xy(after[i]["center"]), "from": _xy(before[i]["center"])}
           for i in ch.get("moved", []) if i in before and i in after]
    out += [{"kind": "removed", "class": before[i]["class"], "at": _xy(before[i]["center"]), "from": None}
            for i in ch.get("removed", []) if i in before]
    out += [{"kind": "added", "class": after[i]["class"], "at": _xy(after[i]["center"]), "from": None}
            for i in ch.get("added", []) if i in after]
    return out


def _reported(report: ChangeReport) -> list[dict]:
    return [{"kind": c.kind, "class": c.cls, "at": _xy(c.center),
             "from": None if c.from_center is None else _xy(c.from_center)} for c in report.changes]


def _match(a: list[dict], b: list[dict], cost) -> int:
    """How many one-to-one pairs (nearest first) ``cost(x, y)`` allows (None = not a pair)."""
    cands = sorted((d, i, j) for i, x in enumerate(a) for j, y in enumerate(b) if (d := cost(x, y)) is not None)
    took_a, took_b = set(), set()
    for _, i, j in cands:
        if i not in took_a and j not in took_b:
            took_a.add(i)
            took_b.add(j)
    return len(took_a)


def _events(changes: list[dict]) -> list[dict]:
    out = []
    for c in changes:
        if c["kind"] in ("added", "moved"):
            out.append({"kind": "appeared", "class": c["class"], "at": c["at"], "from": None})
        if c["kind"] == "removed":
            out.append({"kind": "disappeared", "class": c["class"], "at": c["at"], "from": None})
        if c["kind"] == "moved":
            out.append({"kind": "disappeared", "class": c["class"], "at": c["from"], "from": None})
    return out


def _ratio(n, d):
    return None if d == 0 else n / d


def evaluate_changes(report: ChangeReport, gt_before: dict, gt_after: dict, tolerance: float = 1.0) -> dict:
    """Precision and recall of ``report`` by change and by place (module docstring)."""
    truth, rep = truth_changes(gt_before, gt_after), _reported(report)

    def cost(x, y):
        if x["kind"] != y["kind"] or x["class"] != y["class"]:
            return None
        d = float(np.linalg.norm(x["at"] - y["at"]))
        if x["from"] is not None:
            d = max(d, float(np.linalg.norm(x["from"] - y["from"])))
        return d if d <= tolerance else None

    out = {"truth": len(truth), "reported": len(rep)}
    for name, a, b in (("by_change", rep, truth), ("by_place", _events(rep), _events(truth))):
        right = _match(a, b, cost)
        out[name] = {"right": right, "reported": len(a), "true": len(b),
                     "precision": _ratio(right, len(a)), "recall": _ratio(right, len(b))}
    return out

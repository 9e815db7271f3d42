"""Class vectors: a detector's scores in the map's class list (other last), and the top class."""

from __future__ import annotations

import numpy as np


class ClassMapper:
    """Turns a detector's score vectors (K,) into the map's class vectors (C+1,), other last.

    Scores of classes that the map does not hold are dropped. The probability mass a detector leaves
    unassigned (1 - sum) is, with ``unassigned="spread"``, spread evenly over every entry but the top
    one: the least informative completion, which neither favours another class nor pushes the object
    towards removal. With ``unassigned="classes"`` it goes to the classes in proportion to their
    scores (other gets none): a detection says that something is there, and what is unsure is only
    which class, so a weak detector's 0.45 for a keyboard does not make the keyboard's map vector
    so flat that three misses outweigh fifty detections.
    """

    def __init__(self, detector_classes: list[str], map_classes: list[str], unassigned: str = "spread"):
        self.unassigned = unassigned
        pos = {c: i for i, c in enumerate(map_classes)}
        self.src = np.array([i for i, c in enumerate(detector_classes) if c in pos], dtype=int)
        self.dst = np.array([pos[detector_classes[i]] for i in self.src], dtype=int)
        self.size = len(map_classes) + 1

    def __call__(self, scores: np.ndarray):
        v = np.zeros(self.size)
        np.add.at(v, self.dst, np.asarray(scores, dtype=np.float64)[self.src])
        total = v.sum()
        if total <= 0:
            return None
        if total > 1 or self.unassigned == "classes":
            return v / total
        top = int(v.argmax())
        rest = np.ones(self.size, dtype=bool)
        rest[top] = False
        v[rest] += (1.0 - total) / rest.sum()
        return v

"""The per-class detection rates a map learns while it is built (``maintenance.learn_detection_rate``),
and the eq. 4 vectors they give: the mapper's bookkeeping of them, apart from the stage's maths
(``maintenance.learnt_detection_rate``, ``v_other_from_detection_rate``)."""

from __future__ import annotations

import numpy as np

from ltc_cli.map.model import ACTIVE, SemanticMap, top_class
from ltc_cli.pipeline.maintenance import (
    class_hit_counts, learnt_detection_rate, non_detection_vectors, v_other_from_detection_rate,
)


class DetectionRates:
    """Clear views and detections (hits) per class (C,) over the confirmed active objects of a map.

    The counts always equal a recount over the object table (a resumed ingest learns exactly what an
    uninterrupted one does): whoever changes an object calls :meth:`touch` before and :meth:`settle`
    after, and the counts move by the difference.
    """

    def __init__(self, smap: SemanticMap, m_cfg: dict):
        self.map = smap
        self.cfg = m_cfg
        self.confirmed = max(1, int(m_cfg["min_detections"]))
        t = smap.objects
        rows = smap.active_rows()
        rows = rows[t.n_det[rows] >= self.confirmed]
        self.views, self.hits = class_hit_counts(
            top_class(t.scores[rows]), t.n_clear[rows], t.n_clear_det[rows], len(smap.classes))
        self._touched: dict = {}
        self._fixed_vectors = None
        self._fixed_vectors = self.vectors()

    def _contribution(self, row: int):
        """(class, clear views, hits) that ``row`` adds to the per-class counts, or None."""
        t = self.map.objects
        if t.status[row] != ACTIVE or t.n_det[row] < self.confirmed:
            return None
        return int(top_class(t.scores[row])), int(t.n_clear[row]), int(t.n_clear_det[row])

    def touch(self, row: int) -> None:
        """Remember what ``row`` counted for before it changes (a row past the table: a new object)."""
        if row not in self._touched:
            self._touched[row] = self._contribution(row) if row < self.map.objects.n else None

    def settle(self) -> None:
        """Apply the changes of the touched rows to the per-class counts."""
        for row, before in self._touched.items():
            for sign, c in ((-1, before), (1, self._contribution(row))):
                if c is not None:
                    self.views[c[0]] += sign * c[1]
                    self.hits[c[0]] += sign * c[2]
        self._touched.clear()

    def vectors(self) -> np.ndarray:
        """Eq. 4 vectors (C, C+1) by the object's class: v_Other from a calibration where it gives
        one, else from the detection rate learnt on this map (``learn_detection_rate``), else the
        configured v_Other."""
        m_cfg = self.cfg
        if not m_cfg["learn_detection_rate"] and self._fixed_vectors is not None:
            return self._fixed_vectors  # nothing learnt: the same every frame
        v = np.full(len(self.map.classes), float(m_cfg["v_other"]))
        if m_cfg["learn_detection_rate"]:
            rate = learnt_detection_rate(self.views, self.hits, m_cfg["rate_prior"], m_cfg["rate_prior_views"])
            v = v_other_from_detection_rate(rate, m_cfg["rate_score"], m_cfg["rate_margin"])
        given = m_cfg["v_other_per_class"] or {}
        v = np.array([float(given.get(c, vc)) for c, vc in zip(self.map.classes, v)])
        return non_detection_vectors(self.map.classes, 0.0, dict(zip(self.map.classes, v)))

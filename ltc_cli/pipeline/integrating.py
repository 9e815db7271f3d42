"""Map integration (DESIGN.md 1.3) of one matched detection: the box by the Defined flags, the
class vector by eq. 3. A part of :class:`~ltc_cli.pipeline.mapper.Mapper`, kept in its own file: the
decisions come from integration.py; these methods apply them to the object table and log them.
"""

from __future__ import annotations

import numpy as np

from ltc_cli.geometry.boxes import Box
from ltc_cli.map.model import ACTIVE, top_class
from ltc_cli.pipeline.association import foreign_geometry
from ltc_cli.pipeline.carving import carve_box
from ltc_cli.pipeline.integration import (
    fuse_scores, integrate_box, label_weight, moved_elsewhere, stale_weight, takes_in,
)


class BoxIntegration:
    """The integration step of :class:`~ltc_cli.pipeline.mapper.Mapper` (it provides ``map``,
    ``cfg``, ``per_class``, ``rates``, ``index``, ``session``, ``_moves`` and the helpers these methods
    call)."""

    def _integrate(self, row, det_box: Box, s_det, frame_index, frame_key) -> bool:
        """Stage 3 on one matched detection: the box by the Defined flags, the class vector by eq. 3.
        Returns whether the detection shaped the box (not another object's geometry, nor a move
        that waits for the old place to be seen empty): then it bounds free-space carving."""
        t = self.map.objects
        self.rates.touch(row)
        i_cfg = self.cfg["integration"]
        obj = t.box(row)
        moves = i_cfg["stale_partial_moves"]
        shaped = True
        if self._foreign(s_det, t.scores[row], det_box, obj):
            new, shaped = obj, False  # the class evidence fuses; the geometry of a different object does not
        elif moves and moved_elsewhere(det_box, obj, t.last_session[row] < self.session):
            new = det_box  # the object was moved: its old box is where it was, the detection where it is
            if moves == "seen-empty":  # ... once stage 4 sees its old place empty in this frame
                new, self._moves[row], shaped = obj, det_box, False
        else:
            w_obj = stale_weight(self._weight(row), t.last_session[row] < self.session, i_cfg["stale_box_weight"])
            new = integrate_box(det_box, obj, 1.0, w_obj, i_cfg["erosion"], self.cfg["modeling"]["min_extent"],
                                part_volume=i_cfg["defined_part_volume"],
                                round_footprint=bool(self.per_class.round_footprint[top_class(t.scores[row])]))
            if int(top_class(s_det)) == int(top_class(t.scores[row])):
                new = self._outgrown(det_box, obj, 1.0, w_obj, int(top_class(s_det)), (row,), new)
        t.set_box(row, new)
        same = int(top_class(s_det)) == int(top_class(t.scores[row]))
        w = label_weight(self._weight(row), float(t.n_det[row] + t.n_nondet[row]), same, i_cfg["relabel_weight"])
        # An earlier session's label, against this session's first detection that says otherwise,
        # weighs at most stale_label_weight: a weak label re-opens, a clear one stays.
        w = stale_weight(w, not same and t.last_session[row] < self.session, i_cfg["stale_label_weight"])
        t.cols["scores"][row] = fuse_scores(s_det, t.scores[row], w)  # eq. 3
        t.cols["n_det"][row] += 1
        self._seen(row, frame_index)
        self._count_view(row)
        self.index.insert(row, new.center, new.size)
        self._log(frame_index, frame_key, "updated", row + 1)
        return shaped

    def _carve(self, detected: dict, T_camera_map: np.ndarray, depth_m: np.ndarray, intr) -> None:
        """Free-space carving (:func:`~ltc_cli.pipeline.carving.carve_box`) of the objects a frame
        detected: ``detected`` maps each row to the box enclosing its detections in the frame that
        shaped it (see :meth:`_integrate`)."""
        i_cfg, t = self.cfg["integration"], self.map.objects
        for row, det_box in detected.items():
            if t.status[row] != ACTIVE:
                continue
            old = t.box(row)
            new = carve_box(old, det_box, T_camera_map, depth_m, intr, i_cfg["free_space_step"],
                            i_cfg["free_space_max_share"], i_cfg["free_space_tolerance"],
                            self.cfg["maintenance"]["ray_step"])
            if new is not old:
                t.set_box(row, new)
                self.index.insert(row, new.center, new.size)

    def _outgrown(self, obs: Box, obj: Box, w_obs: float, w_obj: float, top: int, rows, plain: Box) -> Box:
        """``plain`` (the paper's box of ``obs`` integrated into ``obj``, both of class ``top``), or
        the box ``partial_outgrow`` grows from a partial one reaching beyond a Defined one, unless
        that box takes in an active object of another class (:func:`takes_in`); ``rows`` are the
        objects being shaped."""
        outgrow = self.per_class.outgrow[top]
        if outgrow is None or obs.defined == obj.defined:
            return plain
        grown = integrate_box(obs, obj, w_obs, w_obj, self.cfg["integration"]["erosion"],
                              self.cfg["modeling"]["min_extent"], outgrow, self._outgrow_turn,
                              part_volume=self.cfg["integration"]["defined_part_volume"])
        if np.array_equal(grown.size, plain.size) and np.array_equal(grown.center, plain.center):
            return plain
        t, r = self.map.objects, float(np.hypot(*grown.size[:2])) / 2
        near = self.index.query(grown.center[0] - r, grown.center[0] + r, grown.center[1] - r, grown.center[1] + r)
        near = near[(t.status[near] == ACTIVE) & ~np.isin(near, rows)]
        near = near[top_class(t.scores[near]) != top]
        return plain if takes_in(grown, plain, t.center[near], t.yaw[near], t.size[near]) else grown

    def _foreign(self, s_a, s_b, box_a: Box, box_b: Box) -> bool:
        """True when box a must not reshape box b: another top class and a dissimilar volume."""
        return foreign_geometry(int(top_class(s_a)), int(top_class(s_b)), box_a.size, box_b.size,
                                self.cfg["association"]["other_class_volume_ratio"])

"""Data association (DESIGN.md 1.2) of one detection: which map object in view takes it, by eq. 2
under the class thresholds, then by containment or by adjoining a partial piece. A part of
:class:`~ltc_cli.pipeline.mapper.Mapper`, kept in its own file: the decisions come from
association.py; these methods feed it the candidates and this frame's depth.
"""

from __future__ import annotations

import numpy as np

from ltc_cli.geometry.boxes import Boxes
from ltc_cli.map.model import top_class
from ltc_cli.pipeline.association import (
    ADJOIN_ELONGATED, adjoining_partial, apart_grounds, containing_candidate, containment, footprint_gaps,
    half_diagonals, long_axis_turns, match_reach, nearest_under_threshold, seen_elsewhere, similar_volume,
    size_caps, thresholds_for, too_long_together, unlike_heights, within_reach,
)
from ltc_cli.pipeline.maintenance import standing_in_box


class DetectionAssociation:
    """The association step of :class:`~ltc_cli.pipeline.mapper.Mapper` (it provides ``map``,
    ``cfg``, ``metric``, ``per_class`` and ``_depth_view``, the frame being mapped)."""

    def _associate(self, det: Boxes, det_class: int, rows: np.ndarray, det_defined: bool = True,
                   this_frame: np.ndarray | None = None) -> tuple[int, bool]:
        """(row or -1, matched by containment) of one detection among candidate rows (stage 2).
        this_frame: (M,) bool, the rows an earlier detection of this frame already took."""
        if rows.size == 0:
            return -1, False
        a_cfg, t = self.cfg["association"], self.map.objects
        reach = match_reach(self.metric, a_cfg)
        share = float(self.per_class.adjoin_share[det_class]) if a_cfg["partial_adjoin_gap"] is not None else 0.0
        this_frame = np.zeros(rows.shape, dtype=bool) if this_frame is None else this_frame
        if reach is not None and rows.size > 8:  # only those that can match decide (the same decision)
            # An adjoining gap of share x the longer side is within 2 share x the half diagonals.
            grow = 1.0 + 2.0 * share
            near = within_reach(det.center[0], grow * half_diagonals(det.size)[0], t.center[rows],
                                grow * half_diagonals(t.size[rows]), reach)
            rows, this_frame = rows[near], this_frame[near]
            if rows.size == 0:
                return -1, False
        cand_classes, cand = top_class(t.scores[rows]), t.boxes(rows)
        dist = self.metric.distance(det, cand)
        larger = size_caps(det.size[0], t.size[rows], 1.0)  # the larger half diagonals, once for both caps
        caps = [None if a_cfg[k] is None else a_cfg[k] * larger for k in ("other_class_scale", "same_class_scale")]
        thr = thresholds_for(det_class, cand_classes, a_cfg["threshold_same_class"], a_cfg["threshold_other_class"],
                             *caps)
        other = cand_classes != det_class
        unlike = other & unlike_heights(
            det.center[0, 2], det.size[0, 2], det_defined, t.center[rows, 2], t.size[rows, 2], t.defined[rows],
            a_cfg["other_class_height_ratio"])
        unlike |= apart_grounds(det, cand, other & ~unlike & (dist <= thr), a_cfg["other_class_min_overlap"])
        if det_defined and a_cfg["defined_min_overlap"] is not None:
            # Whole views of one thing overlap; a whole box beside an object of this session is
            # another thing (objects of earlier sessions: a drive's drift may put it beside).
            whole = ~other & t.defined[rows] & (t.first_session[rows] == self.session)
            unlike |= apart_grounds(det, cand, whole & ~unlike & (dist <= thr), a_cfg["defined_min_overlap"])
        if a_cfg["seen_apart_gap"] is not None and self._depth_view is not None:
            unlike |= self._seen_elsewhere(det, cand, ~unlike & (dist <= thr))
        too_long = (cand_classes == det_class) & too_long_together(
            np.broadcast_to(det.corners[:1, :4, :2], (len(rows), 4, 2)), cand.corners[:, :4, :2],
            self.per_class.max_union[det_class])
        unlike |= too_long
        best = nearest_under_threshold(dist, np.where(unlike, -1.0, thr))
        if best >= 0:
            return int(rows[best]), False
        if not a_cfg["containment"]:
            return -1, False
        comparable = similar_volume(np.prod(det.size, axis=1), np.prod(cand.size, axis=1),
                                    a_cfg["other_class_volume_ratio"]) & ~unlike
        best = containing_candidate(containment(det, cand), cand_classes == det_class, a_cfg["containment"],
                                    a_cfg["containment_other_class"], comparable)
        if best < 0 and not det_defined and not self.per_class.no_adjoin[det_class]:
            long_sides = np.maximum(det.size[0, :2].max(), cand.size[:, :2].max(axis=1))
            pieces = ~t.defined[rows] & ~too_long & (True if a_cfg["adjoin_same_frame"] else ~this_frame)
            if a_cfg["seen_apart_gap"] is not None and self._depth_view is not None:
                # Small things adjoin no piece the depth shows standing in its own box: pieces of a
                # long object (a table end by end) stand in theirs too, but are not small.
                small = long_sides <= self.cfg["maintenance"]["occupied_max_width"]
                pieces &= ~self._seen_elsewhere(det, cand, pieces & small & (cand_classes == det_class))
            turn = (a_cfg["adjoin_max_turn"] or {}).get(self.map.classes[det_class])
            if turn is not None:  # pieces of one flat, straight thing lie along one line
                pieces &= long_axis_turns(det.yaw[0], det.size[0], cand.yaw, cand.size,
                                          ADJOIN_ELONGATED) <= np.radians(turn)
            best = adjoining_partial(footprint_gaps(det, cand), cand_classes == det_class, pieces,
                                     a_cfg["partial_adjoin_gap"], long_sides, share)
        return (int(rows[best]), True) if best >= 0 else (-1, False)

    def _seen_elsewhere(self, det: Boxes, cand: Boxes, judged: np.ndarray) -> np.ndarray:
        """(M,) bool: of the candidates ``judged`` marks, those :func:`seen_elsewhere` parts from the
        detection in this frame's depth; the depth is cast only for those apart from it."""
        min_gap = self.cfg["association"]["seen_apart_gap"]
        out, idx = np.zeros(judged.shape, dtype=bool), np.flatnonzero(judged)
        gaps = footprint_gaps(det, cand.take(idx))
        idx, gaps = idx[gaps > min_gap], gaps[gaps > min_gap]
        if idx.size:
            out[idx] = seen_elsewhere(gaps, self._standing(cand.take(idx)), min_gap)
        return out

    def _standing(self, boxes: Boxes) -> np.ndarray:
        """:func:`standing_in_box` in the frame being mapped."""
        T_map_camera, depth_m, intr, depth_range = self._depth_view
        return standing_in_box(boxes, T_map_camera, depth_m, intr, depth_range, self.cfg["maintenance"],
                               self.cfg["association"]["seen_apart_share"])

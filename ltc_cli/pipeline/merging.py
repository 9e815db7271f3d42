"""Instance de-duplication (DESIGN.md 1.2): after a frame, the map objects in view that now match
each other become one. A part of :class:`~ltc_cli.pipeline.mapper.Mapper`, kept in its own file:
the decisions (which pairs merge, which one keeps its id, the merged box and class vector) come
from deduplication.py and integration.py; these methods apply them to the object table and log them.
"""

from __future__ import annotations

import numpy as np

from ltc_cli.geometry.camera import invert_pose
from ltc_cli.map.model import ACTIVE, MERGED, top_class
from ltc_cli.pipeline.association import footprint_gaps, match_reach, seen_elsewhere
from ltc_cli.pipeline.deduplication import (
    PIECES_KEY, beyond_class_length, enclosed_part, greedy_merges, label_survivor, merge_pairs,
)
from ltc_cli.pipeline.frame_modeling import not_whole
from ltc_cli.pipeline.integration import (
    confirmed_side, enclosing_box, label_weight, merge_objects, merged_box, merged_scores, one_view_claims,
    stale_side,
)
from ltc_cli.pipeline.maintenance import tentative
from ltc_cli.pipeline.views import union_span
from ltc_cli.pipeline.stands import stand_pairs


class InstanceMerging:
    """The merge step of :class:`~ltc_cli.pipeline.mapper.Mapper` (it provides ``map``, ``cfg``,
    ``metric``, ``per_class``, ``rates``, ``index``, ``session`` and the helpers these methods call)."""

    def _merge_in_view(self, frame_index, frame_key, T_camera_map, intr, max_depth) -> int:
        """Instance de-duplication: in-view map objects that now match each other become one. With
        ``merge_recheck``, in rounds: each object in one merge per round, the pairs found again on
        the merged boxes, until none is left."""
        t = self.map.objects
        rows = self._candidates(invert_pose(T_camera_map), T_camera_map, intr, max_depth)
        if rows.size < 2:
            return 0
        recheck = bool(self.cfg["association"]["merge_recheck"])
        done = 0
        while rows.size >= 2:
            merged = self._merge_round(rows, frame_index, frame_key, recheck)
            done += merged
            rows = rows[t.status[rows] == ACTIVE]
            if not merged or not recheck:
                break
        return done + self._merge_stands(rows, frame_index, frame_key)  # rows: the active ones by now

    def _merge_round(self, rows: np.ndarray, frame_index, frame_key, disjoint: bool) -> int:
        """One round of :meth:`_merge_in_view` over ``rows`` (active, in view): the merges it made."""
        t = self.map.objects
        a_cfg = self.cfg["association"]
        top = top_class(t.scores[rows])
        # defined_min_width holds for map objects too: a Defined "couch" end of a bed that its class
        # evidence later calls bed is a part of the bed (stage 1 judged it under its label then).
        defined = not_whole(t.defined[rows], t.size[rows, :2].max(axis=1), self.per_class.whole_width[top])
        pairs = merge_pairs(t.boxes(rows), top, self.metric.distance, a_cfg,
                            match_reach(self.metric, a_cfg), defined, t.first_session[rows], self.session,
                            t.scores[rows], self.cfg["integration"]["defined_part_volume"],
                            self.per_class.adjoin_share if a_cfg["merge_adjoining"] else None,
                            self.per_class.container_width, t.n_det[rows], self.per_class.max_union,
                            paired=bool(getattr(self.metric, "paired", False)))
        if a_cfg["seen_apart_gap"] is not None and self._depth_view is not None:
            pairs = self._not_seen_apart(rows, pairs)
        if a_cfg["bound_merged_length"] and np.isfinite(self.per_class.max_union).any():
            pairs = [p for p in pairs if top[p[1]] == top[p[2]] or not self._too_long_merged(rows[p[1]], rows[p[2]])]
        merges = greedy_merges(pairs, rows + 1, lambda a, b: self._survivor(rows, a, b), disjoint)
        pieces = {(a, b) for key, a, b in pairs if key >= PIECES_KEY} - {(a, b) for key, a, b in pairs
                                                                          if key < PIECES_KEY}
        if a_cfg["merge_part_under"] and a_cfg["stand_gap"] is not None:
            pieces |= self._parts_under(rows, pairs, top)
        for keep, drop in merges:
            self._absorb(int(rows[keep]), int(rows[drop]), frame_index, frame_key,
                         pieces=(min(keep, drop), max(keep, drop)) in pieces)
        return len(merges)

    def _too_long_merged(self, a: int, b: int) -> bool:
        """Whether merging map objects a and b (rows of two top classes) would make a thing longer
        than its class ever is (:func:`beyond_class_length`): then they stay two."""
        t = self.map.objects
        box, scores = self._merged(min(a, b), max(a, b))
        rows = [a, b]
        return beyond_class_length(int(top_class(scores)), float(box.size[:2].max()), top_class(t.scores[rows]),
                                   t.size[rows, :2].max(axis=1), self.per_class.max_union)

    def _not_seen_apart(self, rows: np.ndarray, pairs: list) -> list:
        """The merge pairs (key, a, b) over ``rows`` less those :func:`seen_elsewhere` parts: two
        objects apart that this frame's depth shows both standing in their own boxes. Adjoining
        pieces (keys from PIECES_KEY) of anything larger than a small thing (occupied_max_width)
        lie apart by design and stay: a table seen end by end stands in both its boxes."""
        t, min_gap = self.map.objects, self.cfg["association"]["seen_apart_gap"]
        long_side = t.size[rows, :2].max(axis=1)
        small = long_side <= self.cfg["maintenance"]["occupied_max_width"]
        judged = [(a, b) for key, a, b in pairs if key < PIECES_KEY or (small[a] and small[b])]
        gaps = {(a, b): float(footprint_gaps(t.boxes(rows[[a]]), t.boxes(rows[[b]]))[0]) for a, b in judged}
        apart = sorted({r for (a, b), g in gaps.items() if g > min_gap for r in (a, b)})
        if not apart:
            return pairs
        standing = dict(zip(apart, self._standing(t.boxes(rows[apart]))))
        both = [(a, b) for a, b in gaps]
        both_standing = np.array([standing.get(a, False) and standing.get(b, False) for a, b in both], dtype=bool)
        parted = seen_elsewhere(np.array([gaps[p] for p in both]), both_standing, min_gap)
        parted = {p for p, yes in zip(both, parted) if yes}
        return [(key, a, b) for key, a, b in pairs if (a, b) not in parted]

    def _parts_under(self, rows: np.ndarray, pairs: list, top: np.ndarray) -> set:
        """The merge pairs (a, b) over ``rows`` of one class, one Defined and one partial, where the
        smaller stands right under the larger as a stand does (:func:`stand_pairs`, whatever their
        classes): pieces of one object, whose merged box encloses both when the Defined one is the
        smaller (a monitor's foot and neck, "tv" by ``taller_than``, under its screen's partial box;
        a Defined box replacing the partial one took the screen down to its foot)."""
        t, a_cfg = self.map.objects, self.cfg["association"]
        same = {(min(a, b), max(a, b)) for key, a, b in pairs if key < PIECES_KEY and top[a] == top[b]
                and t.defined[rows[a]] != t.defined[rows[b]]}
        if not same:
            return set()
        idx = np.array(sorted({r for p in same for r in p}))
        under = stand_pairs(t.boxes(rows[idx]), np.arange(idx.size), a_cfg["stand_gap"], a_cfg["stand_margin"],
                            low=a_cfg["stand_low"], centred=a_cfg["stand_centred"], within=a_cfg["stand_within"],
                            within_floor=a_cfg["stand_within_floor"] or 0.0)
        return same & {(int(idx[i]), int(idx[j])) for _, i, j in under}

    def _merge_stands(self, rows: np.ndarray, frame_index, frame_key) -> int:
        """A smaller object standing right under a larger one of another class is its lower part
        (:func:`stand_pairs`): the larger keeps its id, box and class vector; the part's label says
        what the detector calls the part, not what the whole is."""
        a_cfg = self.cfg["association"]
        if a_cfg["stand_gap"] is None or rows.size < 2:
            return 0
        t = self.map.objects
        vol = np.prod(t.size[rows], axis=1)
        pairs = stand_pairs(t.boxes(rows), top_class(t.scores[rows]), a_cfg["stand_gap"], a_cfg["stand_margin"],
                            established=t.first_session[rows] < self.session if a_cfg["established_apart"] else None,
                            low=a_cfg["stand_low"], centred=a_cfg["stand_centred"], within=a_cfg["stand_within"],
                            part_of=self.flags.taller_is if a_cfg["stand_inside_parts"] else None,
                            tentative=self._tentative(rows) if a_cfg["stand_confirmed"] else None,
                            within_floor=a_cfg["stand_within_floor"] or 0.0)
        merges = greedy_merges(pairs, rows + 1, lambda a, b: a if vol[a] > vol[b] else b)
        for keep, drop in merges:
            keep, drop = int(rows[keep]), int(rows[drop])
            self.rates.touch(keep)
            self.rates.touch(drop)
            for col in ("n_det", "n_clear", "n_clear_det", "n_flat", "det_holes"):
                t.cols[col][keep] += t.cols[col][drop]
            self._seen(keep, frame_index)
            self._set_status(drop, MERGED)
            self._log(frame_index, frame_key, "merged", keep + 1, drop + 1)
        return len(merges)

    def _tentative(self, rows: np.ndarray) -> np.ndarray:
        """(M,) bool: :func:`~ltc_cli.pipeline.maintenance.tentative` for each row."""
        t = self.map.objects
        return (t.first_session[rows] == self.session) & (t.n_det[rows] < self.cfg["maintenance"]["min_detections"])

    def _merge_weights(self, older: int, newer: int) -> tuple[float, float]:
        t = self.map.objects
        # Two labels of one object: each class vector weighs as its observations (relabel_weight all).
        same = int(top_class(t.scores[older])) == int(top_class(t.scores[newer]))
        return tuple(label_weight(self._weight(r), float(t.n_det[r] + t.n_nondet[r]), same,
                                  self.cfg["integration"]["relabel_weight"]) for r in (older, newer))

    def _merged(self, older: int, newer: int, pieces: bool = False):
        """(box, class vector) of two map objects merged; the older one takes the role of the map
        object and the newer one of the observation, whichever keeps its id. ``pieces``: two pieces
        of one object (:func:`adjoining_part_pairs`); their box encloses both when the Defined one
        is the smaller (:func:`enclosed_part`)."""
        t, i_cfg = self.map.objects, self.cfg["integration"]
        b_old, b_new = t.box(older), t.box(newer)
        # defined_min_width holds for the merged boxes as for the pairs: a Defined box shorter than
        # any whole object of its class (two partial views' union whose corners snapped together)
        # is a part, and does not replace the partial box of the whole (a 0.24 m piece of a 0.5 m
        # monitor did, on tum-fr1-rpy).
        for row, b in ((older, b_old), (newer, b_new)):
            whole = self.per_class.whole_width[top_class(t.scores[row])]
            b.defined = bool(not_whole(b.defined, b.size[:2].max(), whole))
        w_old, w_new = self._merge_weights(older, newer)
        box, scores = merge_objects(b_old, b_new, t.scores[older], t.scores[newer], w_old, w_new,
                                    i_cfg["erosion"], self.cfg["modeling"]["min_extent"],
                                    part_volume=i_cfg["defined_part_volume"],
                                    round_footprint=bool(self.per_class.round_footprint[top_class(t.scores[older])]))
        if pieces and b_old.defined != b_new.defined and enclosed_part(b_old, b_new):
            # A Defined piece smaller than the partial one beside it is not the whole, whatever its
            # vertices said (a Defined end of a table beside a partial box of the rest): the two
            # pieces enclose.
            return enclosing_box(b_new, b_old, i_cfg["erosion"], self.cfg["modeling"]["min_extent"]), scores
        top = int(top_class(t.scores[older]))
        if int(top_class(t.scores[newer])) == top:
            box = self._outgrown(b_new, b_old, w_new, w_old, top, (older, newer), box)
        # A whole box: the confirmed one's against a tentative label (tentative_reshapes false) or a
        # one-view claim (one_view_reshapes false), else the one detected now (merge_current_box);
        # the size rule for foreign boxes holds only when neither chose.
        confirmed = None
        weak = self._weak_claims(older, newer)
        if weak is not None:
            confirmed = confirmed_side(int(top_class(t.scores[older])), int(top_class(t.scores[newer])), *weak)
        side = {"older": "keep", "newer": "drop"}.get(confirmed)
        if side is None and self.cfg["association"]["merge_current_box"]:
            side = stale_side(t.last_session[older] == self.session, t.last_session[newer] == self.session)
        foreign = confirmed is None and self._foreign(t.scores[newer], t.scores[older], b_new, b_old)
        return merged_box(box, b_old, b_new, side, foreign), scores

    def _weak_claims(self, older: int, newer: int) -> tuple[bool, bool] | None:
        """(older, newer): whether each one's box is too weak a claim to reshape the other's in a
        merge (:func:`confirmed_side`): tentative (unless tentative_reshapes), or a one-view claim
        (:func:`one_view_claims`, unless one_view_reshapes); None when both settings are true."""
        t, a_cfg, m_cfg = self.map.objects, self.cfg["association"], self.cfg["maintenance"]
        if a_cfg["tentative_reshapes"] and a_cfg["one_view_reshapes"]:
            return None
        rows = np.array([older, newer])
        weak = np.zeros(2, dtype=bool)
        if not a_cfg["tentative_reshapes"]:
            weak |= [tentative(int(t.first_session[r]), int(t.n_det[r]), self.session, m_cfg["min_detections"])
                     for r in rows]
        if not a_cfg["one_view_reshapes"]:
            weak |= one_view_claims(t.first_session[rows] == self.session, self._confirm_views(rows),
                                    m_cfg["min_detection_views"], t.n_det[rows], np.prod(t.size[rows], axis=1))
        return bool(weak[0]), bool(weak[1])

    def _survivor(self, rows: np.ndarray, a: int, b: int) -> int:
        """Which of rows[a] (older) and rows[b] (newer), about to merge, keeps its id (a or b)."""
        t = self.map.objects
        by_label = self.cfg["association"]["merge_id_by_label"]
        tops = top_class(t.scores[rows[[a, b]]])
        if not by_label or tops[0] == tops[1]:
            return a
        older, newer = int(rows[a]), int(rows[b])
        scores = merged_scores(t.scores[older], t.scores[newer], *self._merge_weights(older, newer))
        only_now = t.first_session[older] < self.session <= t.first_session[newer]
        return b if label_survivor(int(tops[0]), int(tops[1]), int(top_class(scores)), by_label, only_now) else a

    def _absorb(self, keep, drop, frame_index, frame_key, pieces: bool = False) -> None:
        t = self.map.objects
        self.rates.touch(keep)
        self.rates.touch(drop)
        box, scores = self._merged(min(keep, drop), max(keep, drop), pieces)
        t.set_box(keep, box)
        t.cols["scores"][keep] = scores
        for col in ("n_det", "n_nondet", "n_clear", "n_clear_det", "n_flat", "det_holes"):
            t.cols[col][keep] += t.cols[col][drop]
        if t.det_views[drop] > 0:
            span = t.det_span[drop] if t.det_views[keep] == 0 else union_span(t.det_span[keep], t.det_span[drop])
            t.cols["det_span"][keep] = span
        t.cols["det_views"][keep] = max(t.det_views[keep], t.det_views[drop])
        if (t.first_session[drop], t.first_frame[drop]) < (t.first_session[keep], t.first_frame[keep]):
            t.cols["first_session"][keep] = t.first_session[drop]
            t.cols["first_frame"][keep] = t.first_frame[drop]
        self._seen(keep, frame_index)
        self._set_status(drop, MERGED)
        self.index.insert(keep, box.center, box.size)
        self._log(frame_index, frame_key, "merged", keep + 1, drop + 1)

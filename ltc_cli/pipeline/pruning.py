"""The end of a session (DESIGN.md 1.4): the tentative objects that too few detections confirmed,
and those the absence rule finds gone, leave the map. A part of
:class:`~ltc_cli.pipeline.mapper.Mapper`, kept in its own file: the decisions come from
maintenance.py and rejoining.py; these methods apply them to the object table and log them.
"""

from __future__ import annotations

import numpy as np

from ltc_cli.map.model import ACTIVE, REMOVED, top_class
from ltc_cli.pipeline.maintenance import absent_in_session, removed_unconfirmed, unconfirmed
from ltc_cli.pipeline.reasons import (
    absent_detail, joined_detail, reidentified_detail, removed_by_misses, returned_detail, unconfirmed_detail,
)
from ltc_cli.pipeline.rejoining import drifted_match, earlier_duplicates, join_bars, same_class_overlap, small_things
from ltc_cli.pipeline.views import views_apart


class SessionPruning:
    """The end-of-session step of :class:`~ltc_cli.pipeline.mapper.Mapper` (it provides ``map``,
    ``cfg``, ``per_class``, ``policy``, ``rates``, ``session`` and the helpers these methods call)."""

    def prune_unconfirmed(self, min_detections: int, frame_index: int, frame_key: str,
                          min_share: float | None = None) -> int:
        """End of a session: remove the tentative objects created in it that too few detections saw:
        fewer than ``min_detections``, or (with ``min_share``) fewer than that share of the frames
        in which it was clearly visible (:func:`~ltc_cli.pipeline.maintenance.unconfirmed`).

        As a tracker confirms a track after M hits in N chances: a detector's one-off false positive
        (a confused class, a split mask, a blob on a wall) is seen once, a real object in a
        recording is seen again. Objects of earlier sessions are not touched. Returns how many were
        removed.
        """
        t, m_cfg = self.map.objects, self.cfg["maintenance"]
        if m_cfg["return_after_misses"]:
            self._return_missed(max(1, min_detections), frame_index, frame_key)
        min_views = m_cfg["min_detection_views"]
        rows = np.flatnonzero((t.status == ACTIVE) & (t.first_session == self.session))
        seen_from = self._confirm_views()
        rows = rows[unconfirmed(t.n_det[rows], t.n_clear[rows], min_detections, min_share, seen_from[rows], min_views)]
        if m_cfg["confirm_across_sessions"] and len(rows):
            rows = self._confirmed_earlier(rows, seen_from, min_detections, min_share, min_views, frame_index, frame_key)
        if m_cfg["confirm_across_views"] and min_views is not None and len(rows):
            rows = self._confirmed_earlier(rows, seen_from, min_detections, min_share, min_views, frame_index,
                                           frame_key, apart=True)
        if m_cfg["reidentify_margin"] is not None and getattr(self.policy, "removes", True):
            self._reidentify(self._absent(), rows, m_cfg["reidentify_margin"], frame_index, frame_key)
        if m_cfg["earlier_overlap_iou"] is not None:
            self._join_earlier(rows, m_cfg["earlier_overlap_iou"], frame_index, frame_key,
                               m_cfg["earlier_small_overlap_iou"])
        if m_cfg["session_overlap_iou"] is not None:
            self._join_within(rows, m_cfg["session_overlap_iou"], frame_index, frame_key)
        gone = 0
        # A policy that never removes (the static world) says so with ``removes = False``.
        if m_cfg["absent_after_views"] is not None and getattr(self.policy, "removes", True):
            old = self._absent()
            for row in old:
                self._remove(row, frame_index, frame_key, absent_detail(
                    t.clear_in_session[row], t.clear_since_det[row],
                    t.through_since_det[row] if m_cfg["absent_through_views"] is not None else None))
            gone = len(old)  # removed once, as absent (not also as unconfirmed)
        for row in rows:
            self._remove(row, frame_index, frame_key,
                         unconfirmed_detail(t.n_det[row], t.n_clear[row], min_detections, min_share,
                                            seen_from[row], min_views))
        self.rates.settle()
        return len(rows) + gone

    def _absent(self) -> np.ndarray:
        """Rows the absence rule removes at this session's end
        (:func:`~ltc_cli.pipeline.maintenance.absent_in_session`); none when it is off."""
        t, m_cfg = self.map.objects, self.cfg["maintenance"]
        absent = m_cfg["absent_after_views"]
        if absent is None:
            return np.zeros(0, dtype=int)
        # Built-in things go by absent_quiet_sessions of silence only, never by one session's.
        views = np.where(self.per_class.fixture[top_class(t.scores)], np.inf, absent)
        return np.flatnonzero(absent_in_session(
            t.status == ACTIVE, t.first_session, t.last_session, t.clear_session, t.clear_in_session, self.session,
            views, t.clear_since_det, m_cfg["absent_quiet_sessions"], m_cfg["absent_quiet_views"] or absent,
            t.through_since_det, m_cfg["absent_through_views"]))

    def _return_missed(self, min_detections: int, frame_index: int, frame_key: str) -> int:
        """Objects that non-detections removed in this session return, with their ids, where a new
        object of their class detected at least ``min_detections`` times in it stands on their
        footprint (:func:`~ltc_cli.pipeline.rejoining.same_class_overlap`): the new one merges
        into the old (counts and class evidence), whose box becomes the new one's.

        A removal by eq. 4 is a belief that the thing went; detections of it at its place in the
        same drive say it did not, and that its misses were the detector's (or its box was off, and
        its place seen through). On tum-fr1-rpy (int8) a far chair with two detections went after
        three misses, and came back 40 frames later as a new object: an id lost for nothing.
        Returns how many came back."""
        t, gone = self.map.objects, set()
        # The log is append-only by session: this session's events are its tail (a map's log may
        # hold millions of events).
        for e in reversed(self.map.events):
            if e.session != self.session:
                break
            if e.kind == "removed" and removed_by_misses(e.detail) and t.status[e.object_id - 1] == REMOVED:
                gone.add(e.object_id - 1)
        gone = np.array(sorted(gone), dtype=int)
        new = np.flatnonzero((t.status == ACTIVE) & (t.first_session == self.session) & (t.n_det >= min_detections))
        if not len(gone) or not len(new):
            return 0
        new = new[np.argsort(-t.n_det[new], kind="stable")]  # the best evidence first
        top = top_class(t.scores)
        match = same_class_overlap(t.boxes(new), top[new], t.boxes(gone), top[gone])
        back = 0
        for row, k in zip(new, match):
            if k < 0 or t.status[gone[k]] != REMOVED:
                continue
            old = int(gone[k])
            self.rates.touch(old)
            # Its misses are contradicted: the scores they moved to "other" go back to its classes.
            s = t.scores[old].copy()
            s[-1] = 0.0
            t.cols["scores"][old] = s / s.sum() if s.sum() > 0 else t.scores[row]
            t.cols["status"][old] = ACTIVE
            # Where the old box stood the misses saw through: the thing is in the box detected now.
            self._take_over(old, int(row), returned_detail(row + 1, t.n_det[row]), frame_index, frame_key)
            back += 1
        return back

    def _take_over(self, old: int, new: int, detail: str, frame_index: int, frame_key: str,
                   keep_box: bool = False) -> None:
        """The new object merges into the old one, which keeps its id and takes the new one's box
        (where this session saw the thing; with ``keep_box`` its own) and last frame; logged as an
        update with ``detail``."""
        t = self.map.objects
        self._log(frame_index, frame_key, "updated", old + 1, detail=detail)
        box = t.box(old if keep_box else new)
        self._absorb(old, new, frame_index, frame_key)
        t.set_box(old, box)
        self.index.insert(old, box.center, box.size)
        t.cols["last_frame"][old] = t.last_frame[new]

    def _reidentify(self, old, unconfirmed_rows, margin: float, frame_index: int, frame_key: str) -> int:
        """An object the absence rule is about to remove (``old``: this session saw it clearly and
        never detected it) takes, with its id, the confirmed new object of its class within
        ``margin`` metres of its footprint (:func:`~ltc_cli.pipeline.rejoining.drifted_match`):
        the new one merges into it and gives it its box, where this drive saw the thing. An object
        the session's evidence keeps (a potted plant missed beside one carried next to it, in a
        simulated house) is not the new one. Returns how many."""
        t = self.map.objects
        active = t.status == ACTIVE
        new = np.setdiff1d(np.flatnonzero(active & (t.first_session == self.session)), unconfirmed_rows)
        if not len(new) or not len(old):
            return 0
        new = new[np.argsort(-t.n_det[new], kind="stable")]  # the best evidence first
        others = np.setdiff1d(np.flatnonzero(active), np.concatenate([old, new]))
        top = top_class(t.scores)
        match = drifted_match(t.boxes(new), top[new], t.boxes(old), top[old], t.boxes(others), top[others], margin)
        done = 0
        for row, k in zip(new, match):
            if k < 0 or t.last_session[old[k]] == self.session:  # taken by a better-seen new one
                continue
            self._take_over(int(old[k]), int(row), reidentified_detail(row + 1, t.n_det[row]), frame_index, frame_key)
            done += 1
        return done

    def _join_earlier(self, unconfirmed_rows, min_iou: float, frame_index: int, frame_key: str,
                      small_iou: float | None = None) -> int:
        """Each confirmed new object whose footprint overlaps an active object of an earlier session
        of its class by ``min_iou`` (:func:`~ltc_cli.pipeline.rejoining.earlier_duplicates`;
        ``small_iou`` when both are small, :func:`~ltc_cli.pipeline.rejoining.join_bars`) merges
        into it: the earlier one keeps its id and its box (the map's reference for the thing; the
        new box is this drive's drifted copy) and takes the new one's detections and class
        evidence. Returns how many."""
        t = self.map.objects
        active = t.status == ACTIVE
        new = np.setdiff1d(np.flatnonzero(active & (t.first_session == self.session)), unconfirmed_rows)
        old = np.flatnonzero(active & (t.first_session < self.session))
        top = top_class(t.scores)
        bars = join_bars(t.size[new], t.size[old], min_iou, small_iou, self.cfg["maintenance"]["occupied_max_width"])
        pairs = earlier_duplicates(t.boxes(new), top[new], t.boxes(old), top[old], bars)
        for k, j, iou in pairs:
            self._take_over(int(old[j]), int(new[k]), joined_detail(new[k] + 1, t.n_det[new[k]], iou), frame_index,
                            frame_key, keep_box=True)
        return len(pairs)

    def _join_within(self, unconfirmed_rows, min_iou: float, frame_index: int, frame_key: str) -> int:
        """Confirmed small objects of this session (longer side at most ``occupied_max_width``)
        whose footprints overlap one of their class by ``min_iou``
        (:func:`~ltc_cli.pipeline.rejoining.earlier_duplicates`, ``same``) become one: the better
        seen keeps its id and box and takes the other's detections. A localiser's jitter puts a
        small thing's whole views a few centimetres apart within one drive, and eq. 2's size cap and
        ``max_union_length`` keep the two boxes apart in every frame. Returns how many."""
        t = self.map.objects
        new = np.setdiff1d(np.flatnonzero((t.status == ACTIVE) & (t.first_session == self.session)), unconfirmed_rows)
        new = new[small_things(t.size[new], self.cfg["maintenance"]["occupied_max_width"])]
        new = new[np.argsort(-t.n_det[new], kind="stable")]  # the best evidence first
        top = top_class(t.scores)
        pairs = earlier_duplicates(t.boxes(new), top[new], t.boxes(new), top[new], min_iou, same=True)
        for k, j, iou in pairs:
            keep, drop = int(new[j]), int(new[k])
            last = max(t.last_frame[keep], t.last_frame[drop])
            self._take_over(keep, drop, joined_detail(drop + 1, t.n_det[drop], iou), frame_index, frame_key,
                            keep_box=True)
            t.cols["last_frame"][keep] = last
        return len(pairs)

    def _confirmed_earlier(self, rows, seen_from, min_detections, min_share, min_views, frame_index, frame_key,
                           apart: bool = False):
        """``rows`` less those an earlier session's unconfirmed object confirms
        (:func:`~ltc_cli.pipeline.rejoining.same_class_overlap`), which stay (logged).

        ``apart`` (confirm_across_views): only objects that had detections enough in their session
        and lacked a second view alone confirm each other, and only when their views taken
        together are two (:func:`~ltc_cli.pipeline.views.views_apart`). tum-fr1-rpy's monitor
        behind the front one, driven in two halves, is named 5-7 times in each half from one view:
        the same evidence as the whole drive's, which confirms it. A false positive that recurs
        from one view recurs from the same view on the next drive, which this does not count."""
        t, m_cfg = self.map.objects, self.cfg["maintenance"]
        weak = unconfirmed(t.n_det, t.n_clear, min_detections, min_share, seen_from, min_views)
        cand = rows
        if apart:
            enough = ~unconfirmed(t.n_det, t.n_clear, min_detections, min_share)
            weak &= enough
            cand = rows[enough[rows]]
        old = np.flatnonzero(removed_unconfirmed(t.status, t.first_session, t.last_session, weak, self.session, REMOVED))
        top, boxes = top_class(t.scores), t.boxes(cand)
        match = same_class_overlap(boxes, top[cand], t.boxes(old), top[old])
        # A thing already in the map under its class is not confirmed again beside it (a duplicate).
        live = np.setdiff1d(np.flatnonzero(t.status == ACTIVE), rows)
        match[same_class_overlap(boxes, top[cand], t.boxes(live), top[live]) >= 0] = -1
        ok = match >= 0
        if apart and ok.any():
            ok[ok] = views_apart(t.det_span[cand[ok]], t.det_span[old[match[ok]]],
                                 m_cfg["confirm_min_move"], m_cfg["confirm_min_turn"])
        how = "seen from another view" if apart else "unconfirmed"
        for row, k in zip(cand[ok], match[ok]):
            self._log(frame_index, frame_key, "updated", row + 1,
                      detail=f"confirmed: object {old[k] + 1} stood here, {how}, in session {t.last_session[old[k]]}")
        return np.setdiff1d(rows, cand[ok])

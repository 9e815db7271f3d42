"""The mapper: runs the four stages on each frame and applies their decisions to the map.

The stages (modeling.py, association.py, integration.py, maintenance.py) are pure functions over
arrays that return decisions; this file (with its parts associating.py, integrating.py, merging.py and pruning.py)
only feeds them, writes their results into the object table, keeps the grid index current, and
logs every change in the event log. No I/O: the store saves and loads the :class:`SemanticMap`;
ingest drives :class:`Mapper` frame by frame.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ltc_cli.geometry.boxes import Box
from ltc_cli.geometry.camera import invert_pose
from ltc_cli.map.model import ACTIVE, REMOVED, Event, GridIndex, SemanticMap, top_class
from ltc_cli.pipeline.associating import DetectionAssociation
from ltc_cli.pipeline.class_settings import ClassSettings
from ltc_cli.pipeline.integration import enclosing_box, fuse_scores
from ltc_cli.pipeline.integrating import BoxIntegration
from ltc_cli.pipeline.merging import InstanceMerging
from ltc_cli.pipeline.pruning import SessionPruning
from ltc_cli.pipeline.maintenance import (
    count_absence_views, found_again, held_by_depth, in_view, non_detection_vectors, other_leads, other_outweighs,
    hole_shares, own_holes, seen_empty, tentative, view_counts,
)
from ltc_cli.pipeline.views import camera_view, new_view, span_views, widen_span
from ltc_cli.pipeline.pictures import PICTURE_MARGIN, is_picture, picture_hits
from ltc_cli.pipeline.reasons import other_leads_detail, picture_detail
from ltc_cli.pipeline.rates import DetectionRates
from ltc_cli.pipeline.frame_modeling import ClassFlags, FrameModel, model_frame
from ltc_cli.protocols import Metric, Policy
from ltc_cli.settings import Settings
from ltc_cli.types import Intrinsics


@dataclass
class FrameResult:
    detections: int = 0
    boxes: int = 0
    matched: int = 0
    created: int = 0
    merged: int = 0
    non_detections: int = 0
    removed: int = 0
    timings: dict = field(default_factory=dict)


class Mapper(DetectionAssociation, InstanceMerging, BoxIntegration, SessionPruning):
    """Runs the four stages of LTC-Mapping frame after frame on a :class:`SemanticMap`."""

    def __init__(self, smap: SemanticMap, config: Settings, metric: Metric, policy: Policy, session: int = 0):
        self.map = smap
        self.cfg = config
        self.metric = metric
        self.policy = policy
        self.session = session
        self.index = GridIndex(config["index"]["cell_size"])
        t = smap.objects
        active = smap.active_rows()
        self.index.build(active, t.center[active], t.size[active])
        self.flags = ClassFlags.from_settings(smap.classes, config)
        self.per_class = ClassSettings.from_settings(smap.classes, config)
        turn = config["integration"]["partial_outgrow_turn"]
        self._outgrow_turn = None if turn is None else np.radians(turn)
        self.rates = DetectionRates(smap, config["maintenance"])
        self._view = np.zeros(6)  # the camera's view of the frame being mapped (camera_view)
        self._depth_view = None  # (T_map_camera, depth_m, intr, depth_range) of the frame being mapped
        self._moves: dict[int, Box] = {}  # rows whose detection elsewhere awaits their old place seen empty
        v_empty = config["maintenance"]["v_other_seen_empty"]
        self._empty_vectors = non_detection_vectors(smap.classes, v_empty, None) if v_empty is not None else None
        # A policy without a removal rule of its own keeps the paper's: removed once `other` leads.
        self._removals = getattr(policy, "removals", other_leads)

    # -- bookkeeping -------------------------------------------------------------------------
    def _weight(self, row: int) -> float:
        """D of eq. 3: the observations of the object so far, capped by ``integration.max_weight``."""
        t = self.map.objects
        d = float(t.n_det[row] + t.n_nondet[row])
        cap = self.cfg["integration"]["max_weight"]
        return d if cap is None else min(d, float(cap))

    def _log(self, frame_index, frame_key, kind, obj, other=0, detail=""):
        self.map.events.append(Event(self.session, frame_index, frame_key, kind, int(obj), int(other), detail))

    def _candidates(self, T_map_camera, T_camera_map, intr, max_depth) -> np.ndarray:
        """Rows of the active objects in the camera's frustum and depth range (sorted)."""
        cam = T_map_camera[:3, 3]
        reach = max_depth + 0.5
        rows = self.index.query(cam[0] - reach, cam[0] + reach, cam[1] - reach, cam[1] + reach)
        if rows.size == 0:
            return rows
        keep = in_view(self.map.objects.boxes(rows), T_camera_map, intr, max_depth)
        return rows[keep]

    # -- the pipeline ------------------------------------------------------------------------
    def process_frame(
        self,
        frame_index: int,
        frame_key: str,
        masks: list[np.ndarray],
        scores: list[np.ndarray],
        depth_m: np.ndarray,
        T_map_camera: np.ndarray,
        intr: Intrinsics,
        depth_range: tuple[float, float],
        clock=None,
        floor_z: float | None = None,
        stage1: FrameModel | None = None,
        depth_noise: float | None = None,
    ) -> FrameResult:
        """Model, associate, integrate and maintain one frame.

        masks: list of (H, W) bool; scores: list of (C+1,) class vectors over the map's classes.
        T_map_camera: (4, 4) camera-to-map pose (up rotation already applied).
        floor_z: the floor's height in the map frame, when known (grounds floor-standing furniture).
        stage1: the frame's stage 1 made elsewhere (a Dask worker, by :func:`model_frame` from the
        same inputs); then masks and scores are not used, and depth_m is read only where stage 4
        and free-space carving read it (see ltc_cli/ingest/remote.py).
        depth_noise: the sensor's depth error std at 1 m measured on the recording, which
        ``modeling.depth_noise: auto`` uses.
        """
        clock = clock or time.perf_counter
        self._moves.clear()
        T_camera_map = invert_pose(T_map_camera)
        self._view = camera_view(T_map_camera)
        self._depth_view = (T_map_camera, depth_m, intr, depth_range)

        t0 = clock()
        if stage1 is None:
            stage1 = model_frame(masks, scores, depth_m, T_map_camera, intr, depth_range, self.cfg, self.flags,
                                 floor_z, depth_noise)
        res = FrameResult(detections=stage1.detections)
        if len(stage1.flat_xyz) and self.cfg["modeling"]["picture_object_share"] is not None:
            res.removed += self._pictures(stage1, T_map_camera, T_camera_map, intr, depth_range[1], frame_index,
                                          frame_key)
        scores, modeled = stage1.scores, stage1.modeled
        res.boxes = len(modeled.source)
        t1 = clock()

        # Stages 2 + 3: each detection in turn takes the nearest candidate under the threshold, or
        # becomes a new object that later detections of the frame may take.
        in_view_rows = list(self._candidates(T_map_camera, T_camera_map, intr, depth_range[1]))
        matched_rows: set = set()
        detected: dict = {}  # row -> the box enclosing its detections in this frame that shaped it
        t_assoc = 0.0
        for k in range(len(modeled.source)):
            ta = clock()
            s_det = scores[int(modeled.source[k])]
            det_box = modeled.boxes.row(k, bool(modeled.defined[k]))
            rows = np.array(in_view_rows, dtype=np.int64)
            j, partial = self._associate(modeled.boxes.take(slice(k, k + 1)), int(top_class(s_det)), rows,
                                         det_box.defined, np.isin(rows, list(matched_rows)))
            if partial:
                det_box.defined = False
            t_assoc += clock() - ta
            if j >= 0:
                shaped = self._integrate(j, det_box, s_det, frame_index, frame_key)
                res.matched += 1
            else:
                j, shaped = self._create(det_box, s_det, frame_index, frame_key), True
                in_view_rows.append(j)
                res.created += 1
            matched_rows.add(j)
            if shaped:  # every piece of it this frame saw (a split mask) bounds the carving
                detected[j] = enclosing_box(det_box, detected[j], 0.0, 0.0) if j in detected else det_box
        if self.cfg["integration"]["free_space_step"] is not None:
            self._carve(detected, T_camera_map, depth_m, intr)
        t2 = clock()

        # Stage 4: objects that should have been seen and were not get a non-detection (eq. 4).
        rows = np.array(in_view_rows, dtype=np.int64)
        if rows.size:
            matched = np.array([r in matched_rows for r in rows])
            missed, clear, empty, clear_absent, seen_through, held, holes = self._missed(
                rows, matched, T_map_camera, depth_m, intr, depth_range, frame_index)
            vectors = self.rates.vectors()
            empty_vectors = self._empty_vectors if self._empty_vectors is not None else vectors
            cols = self.map.objects.cols
            for row, hit, share in zip(rows[clear], matched[clear], holes[clear]):
                self.rates.touch(int(row))
                cols["n_clear"][row] += 1
                cols["n_clear_det"][row] += int(hit)
                cols["det_holes"][row] += share if hit else 0.0
            count_absence_views(cols, rows, clear_absent, matched, seen_through & ~held, self.session)
            # A stale box moves to a detection nearby when its place is seen through, whatever stands
            # within the drift margin: that may be the thing itself, where the detection is.
            for row in set(rows[clear_absent & seen_through].tolist()) & set(self._moves):
                self.map.objects.set_box(row, self._moves[row])
                self.index.insert(row, self._moves[row].center, self._moves[row].size)
            for row, through in zip(rows[missed], empty[missed]):
                res.non_detections += 1
                res.removed += self._non_detection(int(row), empty_vectors if through else vectors, frame_index,
                                                   frame_key)
        t3 = clock()

        if self.cfg["association"]["merge"]:
            res.merged = self._merge_in_view(frame_index, frame_key, T_camera_map, intr, depth_range[1])
        self.rates.settle()
        t4 = clock()
        res.timings = {"modeling": t1 - t0, "association": t_assoc, "integration": t2 - t1 - t_assoc,
                       "maintenance": t3 - t2, "merge": t4 - t3}
        return res

    def _pictures(self, stage1: FrameModel, T_map_camera, T_camera_map, intr, max_depth, frame_index, frame_key):
        """The frame's detections dropped as flat on a wall count on the in-view objects of their
        class they fall in; objects that are pictures by :func:`is_picture` go. Returns how many."""
        t, p_cfg = self.map.objects, self.cfg["modeling"]
        rows = self._candidates(T_map_camera, T_camera_map, intr, max_depth)
        hits = picture_hits(t.boxes(rows), top_class(t.scores[rows]), stage1.flat_xyz, stage1.flat_top,
                            PICTURE_MARGIN)
        t.cols["n_flat"][rows] += hits
        gone = rows[(hits > 0) & is_picture(t.n_det[rows], t.n_flat[rows], p_cfg["picture_object_share"],
                                            p_cfg["picture_min_views"])]
        for row in gone:
            self._remove(row, frame_index, frame_key, picture_detail(t.n_flat[row], t.n_det[row]))
        return len(gone)

    def _missed(self, rows, matched, T_map_camera, depth_m, intr, depth_range, frame_index=0):
        """(missed, clear, empty, clear for the absence rule, seen through for it, held, holes), each
        (M,) over in-view rows, bool but the last: which get a non-detection, as the maintenance
        policy decides; which were clearly visible (enough pixels to say so); which of the missed
        ones the depth showed to be free space; which were clearly visible by
        ``hidden_by_whole_box`` ("absence": by the whole-box rule); which of those the camera saw
        through (absent_through_share of the pixels past the box's middle); which small things the
        depth shows standing within the drift margin of their box (``held_by_depth``: neither a
        miss nor seen through for the absence rule); and the share of each box's pixels without a
        depth reading (:func:`hole_shares`)."""
        m_cfg = self.cfg["maintenance"]
        boxes = self.map.objects.boxes(rows)
        vis_px, need, empty_px, vis_absent, through_px, need_through, unread = view_counts(
            boxes, T_map_camera, depth_m, intr, depth_range, m_cfg)
        held = held_by_depth(boxes, T_map_camera, depth_m, intr, vis_absent, m_cfg)
        missed = np.asarray(self.policy.non_detections(matched, vis_px, need), dtype=bool) & ~matched & ~held
        if m_cfg["spare_frames"] is not None:
            t = self.map.objects
            missed &= ~found_again(t.first_session[rows], t.last_session[rows], t.last_frame[rows], self.session,
                                   frame_index, m_cfg["spare_frames"])
        if m_cfg["nondet_through_share"] is not None:
            # Where the depth shows something standing in the box, the detector's silence is its own;
            # where it has no reading (nondet_through_holes), it shows nothing either way.
            missed &= seen_empty(vis_absent + unread, through_px, m_cfg["nondet_through_share"])
        empty = missed & seen_empty(vis_px, empty_px, m_cfg["seen_empty_share"])
        if missed.any():
            # A miss where the depth shows free space is not the detector's word but the camera's:
            # it always counts. Others count from a new view only.
            t, view = self.map.objects, camera_view(T_map_camera)
            missed &= empty | new_view(t.nondet_view[rows], view, m_cfg["nondet_min_move"], m_cfg["nondet_min_turn"])
            t.cols["nondet_view"][rows[missed]] = view
        # Holes in the depth are no view of the place, when the thing makes them itself.
        t = self.map.objects
        own = own_holes(t.det_holes[rows], t.n_clear_det[rows], m_cfg["absent_holes_share"])
        through = seen_empty(vis_absent + np.where(own, unread, 0), through_px, m_cfg["absent_through_share"]) \
            if through_px is not None else np.zeros(len(rows), dtype=bool)
        # Where the camera saw through most of what it saw of the box, the depth says the place is
        # empty: that is no detector's silence, and a part of the box is enough to say so.
        clear_absent = (vis_absent >= need) | (through & ~held & (vis_absent >= need_through))
        return missed, vis_px >= need, empty, clear_absent, through, held, hole_shares(vis_absent, unread)

    # -- applying decisions ------------------------------------------------------------------
    def _remove(self, row, frame_index, frame_key, detail) -> None:
        self.rates.touch(int(row))
        self._set_status(int(row), REMOVED)
        self._log(frame_index, frame_key, "removed", row + 1, detail=detail)

    def _set_status(self, row: int, status: int) -> None:
        self.map.objects.cols["status"][row] = status
        self.index.remove(row)

    def _seen(self, row: int, frame_index: int) -> None:
        cols = self.map.objects.cols
        cols["last_session"][row] = self.session
        cols["last_frame"][row] = frame_index
        cols["clear_since_det"][row] = 0
        cols["through_since_det"][row] = 0

    def _confirm_views(self, rows: np.ndarray | None = None) -> np.ndarray:
        """(N,) distinct views of detection per object (or (M,) for ``rows``) for min_detection_views:
        by the span of the views (order-free) when two are asked for, else as counted one after another."""
        t, m_cfg = self.map.objects, self.cfg["maintenance"]
        rows = slice(None) if rows is None else rows
        if m_cfg["min_detection_views"] is None or m_cfg["min_detection_views"] > 2:
            return t.det_views[rows]
        return span_views(t.det_span[rows], t.det_views[rows], m_cfg["confirm_min_move"], m_cfg["confirm_min_turn"])

    def _count_view(self, row: int) -> None:
        """A detection of ``row`` from a new view (confirm_min_move / confirm_min_turn since the
        last counted one) adds one to its distinct views of detection."""
        m_cfg, cols = self.cfg["maintenance"], self.map.objects.cols
        cols["det_span"][row] = widen_span(cols["det_span"][row], self._view, cols["det_views"][row] == 0)
        if new_view(cols["det_view"][row:row + 1], self._view, m_cfg["confirm_min_move"], m_cfg["confirm_min_turn"])[0]:
            cols["det_views"][row] += 1
            cols["det_view"][row] = self._view

    def _create(self, box: Box, s_det, frame_index, frame_key) -> int:
        t = self.map.objects
        self.rates.touch(t.n)
        row = t.append(
            center=box.center, yaw=box.yaw, size=box.size, visible=box.visible, defined=box.defined,
            scores=s_det, n_det=1, n_nondet=0, status=ACTIVE, first_session=self.session,
            first_frame=frame_index, last_session=self.session, last_frame=frame_index,
        )
        self.index.insert(row, box.center, box.size)
        self._count_view(row)
        self._log(frame_index, frame_key, "created", row + 1)
        return row

    def _non_detection(self, row, vectors, frame_index, frame_key) -> bool:
        """Fuse a non-detection into ``row`` (eqs. 3-4, ``vectors`` (C, C+1) by class); remove it
        when the policy says so."""
        t = self.map.objects
        self.rates.touch(row)
        s = fuse_scores(vectors[int(top_class(t.scores[row]))], t.scores[row], self._weight(row))
        t.cols["scores"][row] = s
        t.cols["n_nondet"][row] += 1
        self._log(frame_index, frame_key, "non-detection", row + 1)
        m_cfg = self.cfg["maintenance"]
        if m_cfg["tentative_until_end"] and tentative(t.first_session[row], t.n_det[row], self.session,
                                                      m_cfg["min_detections"]):
            return False  # the confirmation rule judges it at the session's end
        remove = bool(np.asarray(self._removals(s[None]))[0])
        if remove and m_cfg["fixture_existence"] and self.per_class.fixture[int(top_class(s))]:
            # A built-in thing is not carried away: misses count against its being there, not
            # against its leading label alone.
            remove = bool(other_outweighs(s[None])[0])
        if not remove:
            return False
        self._remove(row, frame_index, frame_key, other_leads_detail(s, self.map.classes, t.n_nondet[row], t.n_det[row]))
        return True

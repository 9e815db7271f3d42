"""The semantic map in memory and the per-frame pipeline that runs the four stages on it.

No I/O here: the map store (store.py) saves and loads :class:`SemanticMap`; the CLI drives
:class:`Mapper` frame by frame.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ltc_cli.pipeline.association import containment, nearest_under_threshold, pairwise_containment, thresholds_for
from ltc_cli.geometry.boxes import Boxes
from ltc_cli.geometry.camera import invert_pose
from ltc_cli.map.model import ACTIVE, MERGED, REMOVED, Event, GridIndex, SemanticMap
from ltc_cli.geometry.boxes import Box
from ltc_cli.pipeline.integration import fuse_scores, integrate_box, non_detection_vector
from ltc_cli.pipeline.maintenance import in_view, pixel_counts, required_pixels
from ltc_cli.pipeline.modeling import model_detections
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


class Mapper:
    """Runs the four stages of LTC-Mapping frame after frame on a :class:`SemanticMap`."""

    def __init__(self, smap: SemanticMap, config: dict, metric, policy, session: int = 0):
        self.map = smap
        self.cfg = config
        self.metric = metric
        self.policy = policy
        self.session = session
        self.index = GridIndex(config["index"]["cell_size"])
        t = smap.objects
        for row in smap.active_rows():
            self.index.insert(int(row), t.center[row], t.size[row])
        self.n_classes = len(smap.classes)
        floor = set(config["modeling"]["floor_classes"] or [])
        self.grounded_class = np.array([c in floor for c in smap.classes] + [False])
        priors = config["modeling"]["class_depth"] or {}
        self.depth_prior = np.array([float(priors.get(c, np.nan)) for c in smap.classes] + [np.nan])
        # v_Other of eq. 4 for an object of each class: a calibration may measure it per class (a
        # detector that rarely finds tables says little by not finding one).
        per_class = config["maintenance"]["v_other_per_class"] or {}
        v = [float(per_class.get(c, config["maintenance"]["v_other"])) for c in smap.classes]
        self.nondet_vectors = np.array([non_detection_vector(self.n_classes, vc) for vc in v])  # (C, C+1)

    # -- helpers -----------------------------------------------------------------------------
    def _weight(self, row: int) -> float:
        t = self.map.objects
        d = float(t.n_det[row] + t.n_nondet[row])
        cap = self.cfg["integration"]["max_weight"]
        return d if cap is None else min(d, float(cap))

    def _top_class(self, scores: np.ndarray) -> np.ndarray:
        return np.asarray(scores)[..., :-1].argmax(axis=-1)

    def _log(self, frame_index, frame_key, kind, obj, other=0, detail=""):
        self.map.events.append(Event(self.session, frame_index, frame_key, kind, int(obj), int(other), detail))

    def _candidates(self, T_map_camera, T_camera_map, intr, max_depth) -> np.ndarray:
        cam = T_map_camera[:3, 3]
        reach = max_depth + 0.5
        rows = self.index.query(cam[0] - reach, cam[0] + reach, cam[1] - reach, cam[1] + reach)
        if rows.size == 0:
            return rows
        keep = in_view(self.map.objects.boxes(rows), T_camera_map, intr, max_depth)
        return rows[keep]

    def _distances(self, det_boxes: Boxes, k: int, rows: np.ndarray) -> np.ndarray:
        return self.metric.distance(det_boxes.take(slice(k, k + 1)), self.map.objects.boxes(rows))

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
    ) -> FrameResult:
        """Model, associate, integrate and maintain one frame.

        masks: list of (H, W) bool; scores: list of (C+1,) class vectors over the map's classes.
        T_map_camera: (4, 4) camera-to-map pose (up rotation already applied).
        floor_z: the floor's height in the map frame, when known (grounds floor-standing furniture).
        """
        clock = clock or time.perf_counter
        res = FrameResult(detections=len(masks))
        cfg, t = self.cfg, self.map.objects
        a_cfg = cfg["association"]
        T_camera_map = invert_pose(T_map_camera)

        t0 = clock()
        grounded = np.array([self.grounded_class[int(self._top_class(v))] for v in scores], dtype=bool)
        top = [int(self._top_class(v)) for v in scores]
        modeled = model_detections(masks, depth_m, intr, T_map_camera, cfg["modeling"], depth_range,
                                   grounded=grounded, floor_z=floor_z, class_depth=self.depth_prior[top])
        res.boxes = len(modeled.source)
        t1 = clock()

        # Stage 2 + 3: each detection takes the nearest candidate under the threshold.
        cand = self._candidates(T_map_camera, T_camera_map, intr, depth_range[1])
        cand_list = list(cand)
        matched_rows: set = set()
        t_assoc = 0.0
        for k in range(len(modeled.source)):
            ta = clock()
            s_det = scores[int(modeled.source[k])]
            det_box = Box(modeled.boxes.center[k], float(modeled.boxes.yaw[k]), modeled.boxes.size[k],
                          modeled.boxes.visible[k], bool(modeled.defined[k]))
            rows = np.array(cand_list, dtype=np.int64)
            j = -1
            if rows.size:
                dist = self._distances(modeled.boxes, k, rows)
                thr = thresholds_for(int(self._top_class(s_det)), self._top_class(t.scores[rows]),
                                     a_cfg["threshold_same_class"], a_cfg["threshold_other_class"])
                best = nearest_under_threshold(dist, thr)
                j = int(rows[best]) if best >= 0 else -1
                if j < 0 and a_cfg["containment"]:
                    j = self._containing(modeled.boxes.take(slice(k, k + 1)), int(self._top_class(s_det)), rows)
                    if j >= 0:
                        # A box mostly inside a map object of its class is a partial view of it,
                        # whatever its vertices say (an occluder close behind fools the Z-buffer).
                        det_box.defined = False
            t_assoc += clock() - ta
            if j >= 0:
                self._integrate(j, det_box, s_det, 1.0, frame_index, frame_key)
                matched_rows.add(j)
                res.matched += 1
            else:
                row = t.append(
                    center=det_box.center, yaw=det_box.yaw, size=det_box.size, visible=det_box.visible,
                    defined=det_box.defined, scores=s_det, n_det=1, n_nondet=0, status=ACTIVE,
                    first_session=self.session, first_frame=frame_index,
                    last_session=self.session, last_frame=frame_index,
                )
                self.index.insert(row, det_box.center, det_box.size)
                self._log(frame_index, frame_key, "created", row + 1)
                cand_list.append(row)
                matched_rows.add(row)
                res.created += 1
        t2 = clock()

        # Stage 4: candidates that should have been seen and were not get a non-detection (eq. 4).
        in_view_rows = np.array(cand_list, dtype=np.int64)
        if in_view_rows.size:
            m_cfg = cfg["maintenance"]
            vis_px, proj_px = pixel_counts(t.boxes(in_view_rows), T_map_camera, depth_m, intr,
                                           m_cfg["ray_step"], m_cfg["depth_tolerance"], depth_range)
            matched = np.array([r in matched_rows for r in in_view_rows])
            scale = (intr.width * intr.height) / (640 * 480)  # pixel thresholds are for 640x480
            need = required_pixels(proj_px, m_cfg["min_visible_pixels"] * scale,
                                   m_cfg["min_visible_fraction"], m_cfg["min_pixels_floor"] * scale,
                                   m_cfg["min_visible_share"])
            nondet = self.policy.non_detections(matched, vis_px, need)
            for row in in_view_rows[np.asarray(nondet, dtype=bool) & ~matched]:
                res.non_detections += 1
                if self._non_detection(int(row), frame_index, frame_key):
                    res.removed += 1
        t3 = clock()

        if a_cfg["merge"]:
            res.merged = self._merge_in_view(frame_index, frame_key, T_camera_map, intr, depth_range[1])
        t4 = clock()
        res.timings = {"modeling": t1 - t0, "association": t_assoc, "integration": t2 - t1 - t_assoc,
                       "maintenance": t3 - t2, "merge": t4 - t3}
        return res

    def prune_unconfirmed(self, min_detections: int, frame_index: int, frame_key: str) -> int:
        """End of a session: remove the tentative objects created in it, those that fewer than
        ``min_detections`` detections saw.

        As a tracker confirms a track after a second hit: a detector's one-off false positive (a
        confused class, a split mask, a blob on a wall) is seen once, a real object in a recording
        is seen again. Objects of earlier sessions are not touched. Returns how many were removed.
        """
        t = self.map.objects
        rows = np.flatnonzero((t.status == ACTIVE) & (t.n_det < min_detections) & (t.first_session == self.session))
        for row in rows:
            t.cols["status"][row] = REMOVED
            self.index.remove(int(row))
            self._log(frame_index, frame_key, "removed", row + 1,
                      detail=(f"unconfirmed: {int(t.n_det[row])} detection(s) in the session that created it, "
                              f"fewer than {min_detections}"))
        return len(rows)

    def _containing(self, det: Boxes, det_class: int, rows: np.ndarray) -> int:
        """The same-class candidate that contains most of the detection box (at least
        ``association.containment`` of its volume), or -1."""
        t = self.map.objects
        a_cfg = self.cfg["association"]
        frac = containment(det, t.boxes(rows))
        same = self._top_class(t.scores[rows]) == det_class
        # A detection inside an object of another class is most often that object with its class
        # confused, but it needs to be further inside to say so.
        need = np.where(same, a_cfg["containment"], a_cfg["containment_other_class"] or np.inf)
        frac = np.where(frac >= need, frac, -1.0)
        best = int(frac.argmax())
        return int(rows[best]) if frac[best] >= 0 else -1

    def _integrate(self, row, det_box: Box, s_det, w_det, frame_index, frame_key, log=True):
        t = self.map.objects
        i_cfg = self.cfg["integration"]
        obj = t.box(row)
        new = integrate_box(det_box, obj, w_det, self._weight(row), i_cfg["erosion"],
                            self.cfg["modeling"]["min_extent"])
        t.set_box(row, new)
        t.cols["scores"][row] = fuse_scores(s_det, t.scores[row], self._weight(row))  # eq. 3
        t.cols["n_det"][row] += 1
        t.cols["last_session"][row] = self.session
        t.cols["last_frame"][row] = frame_index
        self.index.insert(row, new.center, new.size)
        if log:
            self._log(frame_index, frame_key, "updated", row + 1)

    def _non_detection(self, row, frame_index, frame_key) -> bool:
        """Fuse a non-detection into ``row`` (eqs. 3-4); remove it when `other` leads. True if removed."""
        t = self.map.objects
        top = int(self._top_class(t.scores[row]))
        s = fuse_scores(self.nondet_vectors[top], t.scores[row], self._weight(row))
        t.cols["scores"][row] = s
        t.cols["n_nondet"][row] += 1
        self._log(frame_index, frame_key, "non-detection", row + 1)
        if int(np.argmax(s)) == self.n_classes:
            t.cols["status"][row] = REMOVED
            self.index.remove(row)
            top = int(s[:-1].argmax())
            detail = (f"other {s[-1]:.3f} > {self.map.classes[top]} {s[top]:.3f} after "
                      f"{int(t.n_nondet[row])} non-detections and {int(t.n_det[row])} detections")
            self._log(frame_index, frame_key, "removed", row + 1, detail=detail)
            return True
        return False

    def _merge_in_view(self, frame_index, frame_key, T_camera_map, intr, max_depth) -> int:
        """Instance de-duplication: in-view map objects that now match each other become one."""
        t = self.map.objects
        rows = self._candidates(invert_pose(T_camera_map), T_camera_map, intr, max_depth)
        if rows.size < 2:
            return 0
        a_cfg = self.cfg["association"]
        boxes = t.boxes(rows)
        top = self._top_class(t.scores[rows])
        if a_cfg["containment"]:
            inside = pairwise_containment(boxes)
            inside = np.maximum(inside, inside.T)  # either one inside the other
            need = np.where(top[:, None] == top[None, :], a_cfg["containment"],
                            a_cfg["containment_other_class"] or np.inf)
            contained = inside >= need
        pairs = []
        for a in range(len(rows) - 1):
            rest = np.arange(a + 1, len(rows))
            dist = self.metric.distance(boxes.take(slice(a, a + 1)), boxes.take(rest))
            thr = thresholds_for(int(top[a]), top[rest], a_cfg["threshold_same_class"],
                                 a_cfg["threshold_other_class"])
            close = dist <= thr
            if a_cfg["containment"]:
                close |= contained[a, rest]  # one object seen in parts
            for b in np.flatnonzero(close):
                pairs.append((float(dist[b]), int(rows[a]), int(rows[rest[b]])))
        merged = 0
        gone: set = set()
        for _, ra, rb in sorted(pairs):
            if ra in gone or rb in gone:
                continue
            keep, drop = (ra, rb) if ra < rb else (rb, ra)  # the older object keeps its id
            self._absorb(keep, drop, frame_index, frame_key)
            gone.add(drop)
            merged += 1
        return merged

    def _absorb(self, keep, drop, frame_index, frame_key) -> None:
        t = self.map.objects
        w_keep, w_drop = self._weight(keep), self._weight(drop)
        i_cfg = self.cfg["integration"]
        new = integrate_box(t.box(drop), t.box(keep), w_drop, w_keep, i_cfg["erosion"],
                            self.cfg["modeling"]["min_extent"])
        t.set_box(keep, new)
        # Eq. 3 generalised to two map objects: the observation-weighted mean of both vectors.
        s = w_keep * t.scores[keep] + w_drop * t.scores[drop]
        t.cols["scores"][keep] = s / s.sum()
        for col in ("n_det", "n_nondet"):
            t.cols[col][keep] += t.cols[col][drop]
        if (t.first_session[drop], t.first_frame[drop]) < (t.first_session[keep], t.first_frame[keep]):
            t.cols["first_session"][keep] = t.first_session[drop]
            t.cols["first_frame"][keep] = t.first_frame[drop]
        t.cols["last_session"][keep] = self.session
        t.cols["last_frame"][keep] = frame_index
        t.cols["status"][drop] = MERGED
        self.index.remove(drop)
        self.index.insert(keep, new.center, new.size)
        self._log(frame_index, frame_key, "merged", keep + 1, drop + 1)

"""A map's boxes drawn into frames of a recording: the way to see whether a map made from real
frames is right. Each box should sit on its thing in every frame that sees it; a box on empty desk,
or one that spills into the aisle, shows at once (numbers alone hide both).

Geometry first, pure numpy: the 12 edges of each box in the camera frame, clipped at the camera's
near plane (an edge that passes behind the camera keeps its part in front), then projected with the
pinhole model (eq. 1 inverted). Drawing is OpenCV's; the frames come from a Recording, and the
sheet is written atomically like every picture ltc writes.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ltc_cli.errors import FrameError
from ltc_cli.fileio import atomic_target
from ltc_cli.geometry.boxes import box_corners
from ltc_cli.geometry.camera import invert_pose, transform
from ltc_cli.map.model import SemanticMap
from ltc_cli.map.query import classify
from ltc_cli.map.render import RenderError, picture_format

#: Box edges as vertex pairs (DESIGN.md section 2: bottom ring 0-3, top ring 4-7 above it).
EDGES = np.array([(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4), (0, 4), (1, 5), (2, 6), (3, 7)])
#: Edges are cut this far (m) in front of the camera: nearer, a projection runs off to infinity.
NEAR = 0.05
#: Ground-truth boxes: thin and light grey, beneath the map's.
TRUTH_RGB = (0.82, 0.82, 0.82)
#: Saturated colours that stand out on a photograph (the top-down picture's palette is made for
#: white paper, and its tv, keyboard and mouse are three purples on a dark desk). RGB in [0, 1].
FRAME_PALETTE = ((1.0, 0.25, 0.25), (0.25, 0.63, 1.0), (0.25, 1.0, 0.25), (1.0, 0.8, 0.0), (1.0, 0.0, 1.0),
                 (0.0, 1.0, 1.0), (1.0, 0.5, 0.0), (0.63, 0.4, 1.0), (1.0, 1.0, 1.0), (0.5, 1.0, 0.63),
                 (1.0, 0.5, 0.75), (0.8, 1.0, 0.0))


def recording_to_map(smap: SemanticMap, recording) -> np.ndarray:
    """T_map_world (4, 4) of a recording: the up rotation its ingest applied (from the map's session
    rows), else the one ingest would apply now."""
    for row in reversed(smap.sessions):
        try:
            ids, ups = json.loads(row.get("recordings") or "[]"), json.loads(row.get("up_rotation") or "[]")
        except ValueError:
            continue
        if recording.identity in ids and len(ups) == len(ids):
            R = np.asarray(ups[ids.index(recording.identity)], dtype=np.float64)
            break
    else:
        from ltc_cli.ingest.frame_setup import frame_setup_for

        R = frame_setup_for(recording).R_up
    T = np.eye(4)
    T[:3, :3] = R
    return T


def clipped_edges(corners_camera: np.ndarray, near: float = NEAR) -> np.ndarray:
    """(E, 2, 3) the parts of a box's 12 edges in front of the plane z = ``near`` of the camera,
    from its corners (8, 3) in the camera frame; edges wholly behind it are left out."""
    a, b = corners_camera[EDGES[:, 0]], corners_camera[EDGES[:, 1]]
    za, zb = a[:, 2], b[:, 2]
    keep = (za >= near) | (zb >= near)
    a, b, za, zb = a[keep], b[keep], za[keep], zb[keep]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(za == zb, 0.0, (near - za) / (zb - za))[:, None]
    cut = a + t * (b - a)
    a = np.where((za < near)[:, None], cut, a)
    b = np.where((zb < near)[:, None], cut, b)
    return np.stack([a, b], axis=1)


def project_points(points_camera: np.ndarray, intr) -> np.ndarray:
    """(..., 2) pixel coordinates (u, v) of camera-frame points (..., 3) in front of the camera."""
    z = points_camera[..., 2]
    return np.stack([intr.fx * points_camera[..., 0] / z + intr.cx, intr.fy * points_camera[..., 1] / z + intr.cy],
                    axis=-1)


@dataclass
class SheetResult:
    path: str
    width: int
    height: int
    frames: list  # the frame keys drawn, in order
    in_view: int  # objects drawn into at least one of them


def in_frustum(centers: np.ndarray, sizes: np.ndarray, T_camera_map: np.ndarray, intr, width: int, height: int,
               max_depth: float = np.inf) -> np.ndarray:
    """(N,) bool: whether each box (centres (N, 3), sizes (N, 3)) may be in the camera's view, up to
    ``max_depth``: its bounding sphere reaches in front of the near plane, no further than
    ``max_depth``, and inside the four planes through the camera and the image's sides. Never
    false for a box with a point in view; a box beside a corner of the view may pass."""
    p = transform(T_camera_map, np.asarray(centers, dtype=np.float64))
    r = 0.5 * np.linalg.norm(sizes, axis=1)
    sides = np.array([[1.0, 0.0, intr.cx / intr.fx], [-1.0, 0.0, (width - intr.cx) / intr.fx],
                      [0.0, 1.0, intr.cy / intr.fy], [0.0, -1.0, (height - intr.cy) / intr.fy]])
    sides /= np.linalg.norm(sides, axis=1, keepdims=True)
    inside = (p @ sides.T >= -r[:, None]).all(axis=1)
    return inside & (p[:, 2] + r >= NEAR) & (p[:, 2] - r <= max_depth)


def draw_boxes(image_rgb: np.ndarray, boxes: list, T_camera_map: np.ndarray, intr, labels: bool = True,
               max_depth: float = np.inf, thickness: int = 2) -> tuple[np.ndarray, set]:
    """A copy of ``image_rgb`` (H, W, 3) with each box of ``boxes`` (id, label, rgb 0-1, center (3,),
    yaw, size (3,)) within ``max_depth`` of the camera drawn as its clipped edges (``thickness``
    px) and (``labels``) labelled "id label" at its highest corner in the image; and the ids of the
    boxes with an edge in the image."""
    import cv2

    img = np.ascontiguousarray(image_rgb.copy())
    h, w = img.shape[:2]
    seen = set()
    if boxes:
        keep = in_frustum(np.array([b[3] for b in boxes]), np.array([b[5] for b in boxes]), T_camera_map, intr, w, h,
                          max_depth)
        boxes = [b for b, k in zip(boxes, keep) if k]
    for oid, label, rgb, center, yaw, size in boxes:
        corners = transform(T_camera_map, box_corners(np.asarray(center), float(yaw), np.asarray(size)))
        segments = clipped_edges(corners)
        if not len(segments):
            continue
        colour = tuple(int(round(255 * c)) for c in rgb)
        drawn = False
        for p, q in project_points(segments, intr):
            ok, p1, p2 = cv2.clipLine((0, 0, w, h), tuple(int(round(x)) for x in p), tuple(int(round(x)) for x in q))
            if ok:
                cv2.line(img, p1, p2, colour, thickness, cv2.LINE_AA)
                drawn = True
        if not drawn:
            continue
        seen.add(oid)
        if not labels:
            continue
        front = corners[corners[:, 2] >= NEAR]
        uv = project_points(front, intr)
        inside = uv[(uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)]
        if len(inside):
            u, v = inside[np.argmin(inside[:, 1])]
            at = (int(min(max(u, 2), w - 120)), int(max(14, v - 4)))
            cv2.putText(img, f"{oid} {label}", at, cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 3, cv2.LINE_AA)
            cv2.putText(img, f"{oid} {label}", at, cv2.FONT_HERSHEY_SIMPLEX, 0.5, colour, 1, cv2.LINE_AA)
    return img, seen


def default_frames(count: int, n: int = 4) -> list[int]:
    """``n`` frame indices spread evenly from the first frame to the last (all of a shorter one)."""
    return np.linspace(0, count - 1, min(n, count)).round().astype(int).tolist() if count else []


def map_boxes(smap: SemanticMap, ids=None) -> list:
    """The active objects (or those of ``ids``) as draw_boxes takes them, a colour a class (by name
    order, so that one map's sheets agree)."""
    cls_idx, _ = classify(smap)
    rows = smap.active_rows()
    names = [smap.classes[int(cls_idx[r])] for r in rows]
    colours = {name: FRAME_PALETTE[k % len(FRAME_PALETTE)] for k, name in enumerate(sorted(set(names)))}
    t = smap.objects
    return [(int(r) + 1, name, colours[name], t.center[r], float(t.yaw[r]), t.size[r])
            for r, name in zip(rows, names) if ids is None or int(r) + 1 in ids]


def frame_sheet(smap: SemanticMap, recording, indices: list[int], out_path, columns: int = 2, scale: float = 1.0,
                ids=None, on_skip=None, max_depth: float = np.inf, truth: list | None = None) -> SheetResult:
    """Draw the map's boxes within ``max_depth`` of each camera into the frames ``indices`` of
    ``recording`` and write them as one picture, ``columns`` frames a row, each scaled by ``scale``;
    ``truth`` (ground-truth objects: class, center, yaw, size, in the map frame) beneath them, thin
    and grey. A frame that cannot be read is passed to ``on_skip(index, FrameError)`` and left out;
    RenderError when none can be."""
    import cv2
    from PIL import Image

    fmt = picture_format(out_path)
    T_map_world = recording_to_map(smap, recording)
    boxes = map_boxes(smap, ids)
    truth_boxes = [(int(o.get("id", 0)), o["class"], TRUTH_RGB, np.asarray(o["center"], np.float64), float(o["yaw"]),
                    np.asarray(o["size"], np.float64)) for o in truth or []]
    tiles, keys, in_view = [], [], set()
    for i in indices:
        try:
            frame = recording.frames[i].load()
            rgb = frame.rgb
        except FrameError as exc:
            if on_skip is not None:
                on_skip(i, exc)
            continue
        if rgb is None:
            rgb = np.zeros(frame.depth_m.shape + (3,), np.uint8)  # a depth-only recording: boxes on black
        T_camera_map = invert_pose(T_map_world @ frame.T_world_camera)
        if truth_boxes:
            rgb, _ = draw_boxes(rgb, truth_boxes, T_camera_map, frame.intrinsics, labels=False, max_depth=max_depth,
                                thickness=1)
        img, seen = draw_boxes(rgb, boxes, T_camera_map, frame.intrinsics, max_depth=max_depth)
        in_view |= seen
        cv2.putText(img, f"frame {frame.key}", (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (0, 0, 0), 4, cv2.LINE_AA)
        cv2.putText(img, f"frame {frame.key}", (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (255, 255, 255), 1, cv2.LINE_AA)
        if scale != 1.0:
            img = cv2.resize(img, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
        tiles.append(img)
        keys.append(frame.key)
    if not tiles:
        raise RenderError("no frame of the recording could be read to draw into", out_path)
    th, tw = max(t.shape[0] for t in tiles), max(t.shape[1] for t in tiles)
    n_rows = -(-len(tiles) // columns)
    sheet = np.zeros((n_rows * th, min(columns, len(tiles)) * tw, 3), np.uint8)
    for k, tile in enumerate(tiles):
        r, c = divmod(k, columns)
        sheet[r * th:r * th + tile.shape[0], c * tw:c * tw + tile.shape[1]] = tile
    try:
        with atomic_target(Path(out_path)) as tmp:
            Image.fromarray(sheet).save(tmp, format=fmt)
    except OSError as exc:
        raise RenderError(f"cannot write the picture ({exc.strerror or exc})", out_path) from None
    return SheetResult(str(out_path), sheet.shape[1], sheet.shape[0], keys, len(in_view))

"""Top-down pictures of a map (like Figure 6 of the LTC-Mapping paper), drawn with matplotlib (Agg).

Each active object's XY footprint is filled semi-transparently and outlined in its class's colour
(fixed per class *name*, so a chair is the same colour in every picture of every map), optionally
labelled "class #id"; ground-truth boxes, when given, are drawn beneath as dashed grey outlines.
The axes are map-frame metres with equal scale, with a scale bar and a legend.

No pyplot: a private :class:`~matplotlib.figure.Figure` on an Agg canvas, so rendering never
touches a display or global state. The canvas is drawn once and its pixel buffer is what is saved,
so :attr:`RenderResult.world_to_pixel` maps map coordinates to exactly those pixels.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ltc_cli.errors import LtcError
from ltc_cli.fileio import atomic_target
from ltc_cli.geometry.boxes import box_corners
from ltc_cli.map.coverage import key_cells
from ltc_cli.map.model import SemanticMap
from ltc_cli.map.query import classify
from ltc_cli.map.render_marks import CHANGE_COLOURS, SEEN_COLOUR, draw_changes, draw_seen, place_labels
from ltc_cli.recordings.groundtruth import read_ground_truth

FILL_ALPHA = 0.35          # footprint fill over the white background
GT_COLOUR = "#6e6e6e"      # ground-truth outlines
MAX_AUTO_LABELS = 300      # beyond this many objects labels are unreadable: off unless asked for
MIN_PIXELS, MAX_PIXELS = 100, 16384

# The fixed palette: Tableau-like colours, distinguishable on white and in print, no greys (grey
# is the ground truth's colour).
PALETTE = (
    "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#bcbd22",
    "#17becf", "#393b79", "#637939", "#8c6d31", "#843c39", "#7b4173", "#3182bd", "#e6550d",
    "#31a354", "#756bb1", "#e7ba52", "#ad494a", "#a55194", "#6baed6", "#fd8d3c", "#74c476",
)
# Common indoor classes (COCO and Robot@VirtualHome names) get chosen entries, so that the usual
# furniture of one picture never shares a colour; any other name takes the entry a CRC of the name
# points at (see class_colour).
_KNOWN = {
    "chair": 0, "table": 1, "dining table": 1, "sofa": 2, "couch": 2, "bed": 3, "tv": 4, "tvmonitor": 4,
    "television": 4, "toilet": 5, "sink": 6, "potted plant": 7, "plant": 7, "refrigerator": 8,
    "fridge": 8, "cabinet": 9, "shelf": 10, "bookshelf": 10, "wardrobe": 11, "desk": 12, "laptop": 13,
    "microwave": 14, "oven": 15, "bench": 16, "nightstand": 17, "lamp": 18, "book": 19, "vase": 20,
    "window": 21, "door": 22, "dishwasher": 23, "washing machine": 17, "bathtub": 21, "shower": 14,
    "clock": 19, "keyboard": 13, "mouse": 20, "cup": 15, "bottle": 22,
}


class RenderError(LtcError):
    """A picture that cannot be made (bad size, unwritable output)."""


def class_colour(name: str) -> tuple[float, float, float]:
    """RGB in [0, 1] of a class name, from the fixed PALETTE: a chosen entry for common classes,
    else the entry at a CRC-32 of the lower-cased name (stable across runs and machines, unlike
    Python's salted ``hash``). Two rare classes may share a colour; the legend names both."""
    key = name.strip().lower()
    idx = _KNOWN.get(key, zlib.crc32(key.encode("utf-8")) % len(PALETTE))
    h = PALETTE[idx].lstrip("#")
    return tuple(int(h[i: i + 2], 16) / 255.0 for i in (0, 2, 4))


def class_colours(names) -> dict[str, tuple[float, float, float]]:
    """A distinct colour for each class of one picture: its :func:`class_colour` unless a class
    before it (common classes first, then by name) took that entry, else the next free entry of the
    PALETTE, and beyond the palette evenly spread hues. So a chair keeps its colour everywhere and no
    two classes of one picture look alike (oven and cup share an entry by their names)."""
    import colorsys

    order = sorted(set(names), key=lambda n: (n.strip().lower() not in _KNOWN, n))
    taken: set[int] = set()
    out = {}
    extra = 0
    for name in order:
        key = name.strip().lower()
        idx = _KNOWN.get(key, zlib.crc32(key.encode("utf-8")) % len(PALETTE))
        free = [i for i in range(len(PALETTE)) if i not in taken]
        if idx in taken:
            idx = min(free, key=lambda i: (i - idx) % len(PALETTE)) if free else None
        if idx is None:  # more classes than palette entries: golden-ratio hues, darker than the fill
            extra += 1
            out[name] = colorsys.hsv_to_rgb((extra * 0.618034) % 1.0, 0.75, 0.8)
            continue
        taken.add(idx)
        h = PALETTE[idx].lstrip("#")
        out[name] = tuple(int(h[i: i + 2], 16) / 255.0 for i in (0, 2, 4))
    return out


def load_ground_truth(path) -> list[dict]:
    """Objects of a ground_truth.json (ltc-ground-truth/1), or of the one in a recording folder.

    Returns the validated list of {id, class, center, yaw, size, ...}; raises RecordingError /
    SchemaError naming the file.
    """
    return list(read_ground_truth(path)["objects"])


@dataclass
class RenderResult:
    """What was drawn. ``world_to_pixel`` (3, 3) maps homogeneous map (x, y, 1) to (column, row, 1)
    in the saved image, origin at the top-left corner of the top-left pixel (pixel (c, r) covers
    [c, c+1) x [r, r+1))."""

    path: str
    width: int
    height: int
    objects: int
    ground_truth: int
    labels: bool
    world_to_pixel: np.ndarray
    xlim: tuple[float, float]
    ylim: tuple[float, float]
    label_boxes: list = None  # pixel boxes (x0, y0, x1, y1) of the labels drawn, origin bottom-left
    changes: dict = None  # {"added": n, "removed": n, "moved": n} drawn with ``changes``
    format: str = "PNG"

    def to_pixel(self, xy) -> np.ndarray:
        """Map points (..., 2) metres -> (..., 2) [column, row] image coordinates (floats)."""
        xy = np.asarray(xy, dtype=np.float64)
        M = self.world_to_pixel
        return xy @ M[:2, :2].T + M[:2, 2]


def _nice_length(span: float) -> float:
    """A 1-2-5 length near a fifth of ``span`` metres, for the scale bar."""
    target = max(span / 5.0, 1e-3)
    base = 10.0 ** math.floor(math.log10(target))
    for m in (5, 2, 1):
        if m * base <= target:
            return m * base
    return base


def _bounds(rings: list[np.ndarray]):
    pts = np.concatenate([r.reshape(-1, 2) for r in rings if r.size]) if any(r.size for r in rings) else None
    if pts is None:
        return (-1.0, 1.0), (-1.0, 1.0)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = max(0.06 * float((hi - lo).max()), 0.3)
    return (float(lo[0] - pad), float(hi[0] + pad)), (float(lo[1] - pad), float(hi[1] + pad))


def render_map(
    smap: SemanticMap,
    out_path,
    *,
    ground_truth: list[dict] | None = None,
    width: int = 1200,
    height: int = 900,
    labels: bool | None = None,
    title: str | None = None,
    bounds: tuple[float, float, float, float] | None = None,
    map_name: str | None = None,
    changes: list | None = None,
    seen: tuple[np.ndarray, float] | None = None,
) -> RenderResult:
    """Draw the map's active objects top-down and write a picture of exactly ``width`` x ``height``:
    PNG, or JPEG / WebP / TIFF / BMP when ``out_path`` ends so (:func:`picture_format`).

    ground_truth: objects as from :func:`load_ground_truth` (dicts with class, center, yaw, size),
        drawn beneath as dashed grey outlines.
    labels: "class #id" at each footprint's centre; None = on when there are at most
        MAX_AUTO_LABELS objects.
    bounds: (xmin, xmax, ymin, ymax) metres to show (then widened on one axis to keep the scale
        equal); default: everything drawn, padded.
    map_name: shown at the start of the default title.
    changes: :class:`~ltc_cli.map.changes.Change` list (``ltc changes``), marked over the map
        (:func:`~ltc_cli.map.render_marks.draw_changes`).
    seen: (cell keys (K,), cell size) of the floor plan sessions saw (map/coverage.sessions_seen),
        shaded beneath everything.
    The file is written atomically (temporary file beside it, then ``os.replace``).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.collections import PolyCollection
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch
    from mpl_toolkits.axes_grid1.anchored_artists import AnchoredSizeBar
    from PIL import Image

    width, height = int(width), int(height)
    for name, v in (("width", width), ("height", height)):
        if not MIN_PIXELS <= v <= MAX_PIXELS:
            raise RenderError(f"{name} must be within {MIN_PIXELS}..{MAX_PIXELS} pixels, not {v}")
    out_path = Path(out_path)
    fmt = picture_format(out_path)

    t = smap.objects
    rows = smap.active_rows()
    cls_idx, _ = classify(smap)
    cls_idx = cls_idx[rows]
    rings = box_corners(t.center[rows], t.yaw[rows], t.size[rows])[:, :4, :2]  # (K, 4, 2) ccw
    gt = list(ground_truth or [])
    gt_rings = (box_corners(np.array([g["center"] for g in gt], dtype=np.float64),
                            np.array([g["yaw"] for g in gt], dtype=np.float64),
                            np.array([g["size"] for g in gt], dtype=np.float64))[:, :4, :2]
                if gt else np.zeros((0, 4, 2)))
    if labels is None:
        labels = len(rows) <= MAX_AUTO_LABELS
    seen_ij = key_cells(seen[0]) if seen is not None and len(seen[0]) else None  # (K, 2) cells shaded

    # Fonts and lines scale with the picture: 100 dpi at 1200 x 900, gently less for small images.
    scale = min(width / 1200.0, height / 900.0)
    dpi = float(np.clip(100.0 * math.sqrt(scale), 40.0, 300.0))
    fig = Figure(figsize=(width / dpi, height / dpi), dpi=dpi, facecolor="white", layout="constrained")
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    ax.set_facecolor("white")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, color="#e4e4e4", linewidth=0.6, zorder=0)
    ax.set_axisbelow(True)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")

    if bounds is not None:
        xlim, ylim = (float(bounds[0]), float(bounds[1])), (float(bounds[2]), float(bounds[3]))
        if not (xlim[1] > xlim[0] and ylim[1] > ylim[0]):
            raise RenderError(f"bounds must be xmin < xmax, ymin < ymax, not {tuple(bounds)}")
    else:
        gone = [box_corners(np.asarray(c.center), c.yaw, np.asarray(c.size))[None, :4, :2]
                for c in changes or () if c.kind != "added"]
        corners = [seen_ij * seen[1], (seen_ij + 1) * seen[1]] if seen_ij is not None else []
        xlim, ylim = _bounds([rings, gt_rings, *gone, *corners])
    # Outlines thinner than the footprints they draw: with thousands of small boxes 1.4 pt lines
    # would cover the fills. ~0.8 of the width is the axes; a tenth of a typical footprint.
    px_per_m = 0.8 * min(width / (xlim[1] - xlim[0]), height / (ylim[1] - ylim[0]))
    typical = float(np.median(t.size[rows, :2].min(axis=1))) if len(rows) else 1.0
    lw = float(np.clip(0.1 * typical * px_per_m * 72.0 / dpi, 0.3, 1.4))

    handles = []
    if seen_ij is not None:
        draw_seen(ax, seen_ij, seen[1])
        handles.append(Patch(facecolor=SEEN_COLOUR, edgecolor="none",
                             label=f"seen by the depth ({len(seen[0]) * seen[1] ** 2:.0f} m2)"))
    if len(gt_rings):
        ax.add_collection(PolyCollection(list(gt_rings), closed=True, facecolors="none", edgecolors=GT_COLOUR,
                                         linestyles=(0, (4, 3)), linewidths=min(1.1, lw), zorder=1))
        handles.append(Line2D([], [], color=GT_COLOUR, linestyle=(0, (4, 3)), linewidth=1.1,
                              label=f"ground truth ({len(gt_rings)})"))
    present = sorted(set(cls_idx.tolist()), key=lambda i: smap.classes[i])
    colours = class_colours(smap.classes[i] for i in present)
    for ci in present:
        sel = cls_idx == ci
        rgb = colours[smap.classes[ci]]
        # Fill and edge colours carry their own alpha: the collection-wide alpha would also fade
        # the outlines.
        ax.add_collection(PolyCollection(list(rings[sel]), closed=True, facecolors=[(*rgb, FILL_ALPHA)],
                                         edgecolors=[(*rgb, 1.0)], linewidths=lw, zorder=2))
        handles.append(Patch(facecolor=(*rgb, FILL_ALPHA), edgecolor=rgb, linewidth=1.4,
                             label=f"{smap.classes[ci]} ({int(sel.sum())})"))
    change_counts = draw_changes(ax, changes, lw) if changes is not None else None
    if change_counts:
        for kind, n in change_counts.items():
            handles.append(Line2D([], [], color=CHANGE_COLOURS[kind], linewidth=2.2,
                                  linestyle=(0, (3, 2)) if kind == "removed" else "solid", label=f"{kind} ({n})"))

    def fit_limits():
        # Set the data limits, not the view limits: with an equal aspect and adjustable="datalim"
        # matplotlib then widens one axis to fill the axes box instead of warning about fixed limits.
        ax.ignore_existing_data_limits = True
        ax.update_datalim([(xlim[0], ylim[0]), (xlim[1], ylim[1])])
        ax.margins(0)
        ax.autoscale_view()

    fit_limits()

    bar = _nice_length(max(xlim[1] - xlim[0], ylim[1] - ylim[0]))
    ax.add_artist(AnchoredSizeBar(ax.transData, bar, f"{bar:g} m", loc="lower left", pad=0.5, borderpad=0.6,
                                  sep=4, frameon=True, size_vertical=0, color="black",
                                  label_top=False))
    if handles:
        fig.legend(handles=handles, loc="outside right upper", frameon=False, fontsize=9)
    n_gt = f", ground truth dashed ({len(gt_rings)})" if len(gt_rings) else ""
    if title is None:
        title = f"{map_name + ': ' if map_name else ''}{len(rows)} objects, {len(present)} classes{n_gt}"
    ax.set_title(title, fontsize=11)

    canvas.draw()
    # The constrained layout moves the axes box while it settles, and each move widens the limits
    # a little; freeze the layout it found and fit the limits to that box once more.
    fig.set_layout_engine("none")
    fit_limits()
    label_boxes = []
    if labels and len(rows):
        # Placed now that the axes are final, so that their pixel extents are the saved ones;
        # the biggest objects choose first.
        order = np.argsort(-(t.size[rows, 0] * t.size[rows, 1]), kind="stable")
        items = [(float(t.center[rows[k], 0]), float(t.center[rows[k], 1]),
                  f"{smap.classes[int(cls_idx[k])]} #{int(rows[k]) + 1}") for k in order]
        label_boxes = place_labels(ax, canvas.get_renderer(), items)
    canvas.draw()
    buf = np.asarray(canvas.buffer_rgba())[..., :3]
    # Figure sizes are floats; guard against a pixel lost to rounding (pad with white / crop).
    if buf.shape[:2] != (height, width):
        img = np.full((height, width, 3), 255, dtype=np.uint8)
        h, w = min(height, buf.shape[0]), min(width, buf.shape[1])
        img[:h, :w] = buf[:h, :w]
        buf = img
    # Display coordinates have their origin at the bottom left; image rows count from the top.
    M = np.array([[1.0, 0, 0], [0, -1.0, float(buf.shape[0])], [0, 0, 1.0]]) @ ax.transData.get_affine().get_matrix()
    xlim_drawn, ylim_drawn = ax.get_xlim(), ax.get_ylim()

    try:
        with atomic_target(out_path) as tmp:
            Image.fromarray(np.ascontiguousarray(buf)).save(tmp, format=fmt, **_SAVE_OPTIONS.get(fmt, {}))
    except OSError as exc:
        raise RenderError(f"cannot write the picture ({exc.strerror or exc})", out_path) from None
    return RenderResult(str(out_path), width, height, int(len(rows)), int(len(gt_rings)), bool(labels), M,
                        tuple(map(float, xlim_drawn)), tuple(map(float, ylim_drawn)), label_boxes,
                        change_counts, fmt)


_FORMATS = {".png": "PNG", ".jpg": "JPEG", ".jpeg": "JPEG", ".webp": "WEBP", ".tif": "TIFF", ".tiff": "TIFF",
            ".bmp": "BMP"}
_SAVE_OPTIONS = {"PNG": {"optimize": False}, "JPEG": {"quality": 92}, "WEBP": {"quality": 92}}


def picture_format(path) -> str:
    """The Pillow format a picture is written in, by the file's suffix (none: PNG)."""
    suffix = Path(path).suffix.lower()
    if not suffix:
        return "PNG"
    if suffix not in _FORMATS:
        raise RenderError(f"cannot write {suffix} pictures (write {', '.join(sorted(_FORMATS))})", path)
    return _FORMATS[suffix]

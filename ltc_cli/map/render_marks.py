"""What :mod:`ltc_cli.map.render` draws over the footprints: labels placed so that they do not
overlap, and the marks of ``ltc render --changes`` (added, removed, moved objects).

Works on a matplotlib Axes whose limits and layout are final (the caller freezes them first), so
that label extents measured in pixels are the ones saved.
"""

from __future__ import annotations

import numpy as np

from ltc_cli.geometry.boxes import box_corners

#: Colours of the change marks (not in the class palette's role: they outline, never fill).
CHANGE_COLOURS = {"added": "#00a651", "removed": "#e4002b", "moved": "#ff8c00"}
# Offsets tried for a label that would cover another, in label heights (dy) and widths (dx).
_OFFSETS = [(0, 0)] + [(dx * k, dy * k) for k in (1, 2, 3) for dx, dy in
                       ((0, 1.1), (0, -1.1), (0.6, 0), (-0.6, 0), (0.6, 1.1), (-0.6, 1.1), (0.6, -1.1), (-0.6, -1.1))]


def _overlaps(box, placed, pad: float = 1.0) -> bool:
    x0, y0, x1, y1 = box
    return any(x0 < b[2] + pad and b[0] < x1 + pad and y0 < b[3] + pad and b[1] < y1 + pad for b in placed)


def place_labels(ax, renderer, items, fontsize: float = 7.0) -> list[tuple[float, float, float, float]]:
    """Write ``items`` [(x, y, text)] (map metres) near their points without overlaps.

    Each label goes at its point if free, else at the nearest free offset of a few label sizes
    (with a thin leader line to its point); a label with no free place is left out. Returns the
    pixel boxes (x0, y0, x1, y1) of the labels written (display coordinates, origin bottom-left).
    """
    placed: list[tuple[float, float, float, float]] = []
    to_px = ax.transData
    for x, y, text in items:
        artist = ax.text(x, y, text, ha="center", va="center", fontsize=fontsize, zorder=5, color="#202020",
                         clip_on=True, bbox=dict(boxstyle="round,pad=0.15", facecolor="white", edgecolor="none",
                                                 alpha=0.75))
        ext = artist.get_window_extent(renderer)
        w, h = ext.width, ext.height
        px, py = to_px.transform((x, y))
        for dx, dy in _OFFSETS:
            cx, cy = px + dx * w, py + dy * h
            box = (cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2)
            if not _overlaps(box, placed):
                break
        else:
            artist.remove()
            continue
        if (dx, dy) != (0, 0):
            artist.set_position(to_px.inverted().transform((cx, cy)))
            # An annotation, not a line: it leaves the data limits (and so the view) alone.
            ax.annotate("", xy=(x, y), xytext=artist.get_position(), zorder=4,
                        arrowprops=dict(arrowstyle="-", color="#808080", linewidth=0.5, shrinkA=0, shrinkB=0))
        placed.append(box)
    return placed


def draw_changes(ax, changes, linewidth: float) -> dict[str, int]:
    """Mark each change: an added object's footprint outlined in green; a removed object's last
    footprint dashed in red with a cross; a moved object outlined in orange with its old footprint
    dashed and an arrow from the old place to the new. Returns how many of each were drawn."""
    from matplotlib.collections import PolyCollection

    counts = {k: 0 for k in CHANGE_COLOURS}
    lw = max(2.0 * linewidth, 1.2)
    for c in changes:
        colour = CHANGE_COLOURS[c.kind]
        ring = box_corners(np.asarray(c.center), c.yaw, np.asarray(c.size))[:4, :2]
        dashed = (0, (3, 2)) if c.kind == "removed" else "solid"
        ax.add_collection(PolyCollection([ring], closed=True, facecolors="none", edgecolors=colour,
                                         linestyles=dashed, linewidths=lw, zorder=3))
        if c.kind == "removed":
            ax.plot(ring[[0, 2], 0], ring[[0, 2], 1], color=colour, linewidth=lw * 0.7, zorder=3)
            ax.plot(ring[[1, 3], 0], ring[[1, 3], 1], color=colour, linewidth=lw * 0.7, zorder=3)
        if c.kind == "moved":
            old = box_corners(np.asarray(c.from_center), c.yaw, np.asarray(c.size))[:4, :2]
            ax.add_collection(PolyCollection([old], closed=True, facecolors="none", edgecolors=colour,
                                             linestyles=(0, (3, 2)), linewidths=lw * 0.7, zorder=3))
            ax.annotate("", xy=c.center[:2], xytext=c.from_center[:2], zorder=4,
                        arrowprops=dict(arrowstyle="->", color=colour, linewidth=lw * 0.8, shrinkA=0, shrinkB=0))
        counts[c.kind] += 1
    return counts


#: The floor plan the sessions' depth saw (map/coverage.py), beneath everything.
SEEN_COLOUR = "#d6e9f8"
#: Cells of the picture's raster at most, a side: a wider map's cells are drawn in blocks.
MAX_SEEN_SIDE = 4096


def draw_seen(ax, cells_ij: np.ndarray, cell: float) -> tuple[float, float, float, float]:
    """Shade the cells (K, 2) int (ix, iy) of ``cell`` metres beneath the map; returns the extent
    (xmin, xmax, ymin, ymax) drawn. One raster, so a city of cells costs one image."""
    from matplotlib.colors import to_rgb

    lo, hi = cells_ij.min(axis=0), cells_ij.max(axis=0)
    block = int(np.ceil((hi - lo + 1).max() / MAX_SEEN_SIDE))
    ij = (cells_ij - lo) // block
    grid = np.zeros(tuple(ij.max(axis=0) + 1), dtype=bool)
    grid[ij[:, 0], ij[:, 1]] = True
    x0, y0 = lo * cell
    x1, y1 = x0 + grid.shape[0] * block * cell, y0 + grid.shape[1] * block * cell
    rgba = np.zeros(grid.T.shape + (4,))
    rgba[grid.T] = (*to_rgb(SEEN_COLOUR), 1.0)
    ax.imshow(rgba, origin="lower", extent=(x0, x1, y0, y1), interpolation="nearest", zorder=0.5, aspect="auto")
    return float(x0), float(x1), float(y0), float(y1)

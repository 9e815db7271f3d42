"""A picture of what an .rrd file written by ``ltc export --format rrd`` / ``ltc view --save`` holds,
read back with rerun's own reader (no viewer, no display): the boxes in 3D with their labels, the
camera path and cameras, and the colour images of the timeline.

    python benchmarks/rrd_picture.py map.rrd -o docs/dining-room-rrd.png

Needs the optional extra ltc[viz]. The Rerun viewer itself needs a GPU or a working software
renderer; this draws the same data with matplotlib where there is neither.
"""

from __future__ import annotations

import argparse
import io
import sys
from pathlib import Path

import numpy as np
from PIL import Image

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from ltc_cli.geometry.boxes import box_corners  # noqa: E402
from ltc_cli.map.render import class_colours  # noqa: E402

EDGES = [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4), (0, 4), (1, 5), (2, 6), (3, 7)]


def read_rrd(path) -> dict[str, dict[str, list]]:
    """{entity path: {column: values of every row}} (time columns left out)."""
    from rerun.chunk import RrdReader

    out: dict[str, dict[str, list]] = {}
    for chunk in RrdReader(str(path)).stream():
        batch = chunk.to_record_batch()
        cols = out.setdefault(chunk.entity_path, {})
        for name in batch.schema.names:
            if name == "frame" or not (name.startswith("rerun.") or "time" in name):
                cols.setdefault(name, []).extend(batch.column(name).to_pylist())
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("rrd")
    ap.add_argument("-o", "--output", required=True)
    args = ap.parse_args()
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    data = read_rrd(args.rrd)
    boxes = data["/world/objects"]
    centers = np.array(boxes["Boxes3D:centers"][0])
    half = np.array(boxes["Boxes3D:half_sizes"][0])
    yaws = np.array([a["angle"] for a in boxes["Boxes3D:rotation_axis_angles"][0]])
    labels = boxes["Boxes3D:labels"][0]
    names = [lb.split(" #")[0] for lb in labels]
    colours = class_colours(names)
    images = [Image.open(io.BytesIO(bytes(b[0]))).convert("RGB") for b in data.get("/world/camera/rgb", {}).get(
        "EncodedImage:blob", [])]

    fig = Figure(figsize=(12, 7.5 if images else 6), dpi=100, facecolor="white")
    FigureCanvasAgg(fig)
    ax = fig.add_axes([0.0, 0.22 if images else 0.0, 1.0, 0.76 if images else 0.95], projection="3d")
    corners = box_corners(centers, yaws, 2 * half)
    for k, (c, name, label) in enumerate(zip(corners, names, labels)):
        for i, j in EDGES:
            ax.plot(*zip(c[i], c[j]), color=colours[name], linewidth=1.6)
        ax.text(*(centers[k] + [0, 0, half[k, 2] + 0.08]), label.split(" (")[0], fontsize=7, ha="center")
    cams = np.array([t[0] for t in data.get("/world/camera", {}).get("Transform3D:translation", []) if t])
    rots = [np.array(m[0]).reshape(3, 3).T for m in data.get("/world/camera", {}).get("Transform3D:mat3x3", []) if m]
    if len(cams):
        ax.plot(*cams.T, color="#e63c3c", linewidth=1.5, marker="o", markersize=3)
        for p, R in zip(cams, rots):  # each camera's viewing direction (its z axis), 0.4 m
            ax.quiver(*p, *(0.4 * R[:, 2]), color="#e63c3c", linewidth=0.8)
    pts = np.concatenate([corners.reshape(-1, 3)] + ([cams] if len(cams) else []))
    mid, span = (pts.max(0) + pts.min(0)) / 2, (pts.max(0) - pts.min(0)).max() / 2
    ax.set_xlim(mid[0] - span, mid[0] + span)
    ax.set_ylim(mid[1] - span, mid[1] + span)
    ax.set_zlim(max(mid[2] - span, pts[:, 2].min() - 0.1), mid[2] + span)
    ax.set_box_aspect((1, 1, 0.6))
    ax.view_init(elev=30, azim=-125)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    ax.set_title(f"{Path(args.rrd).name}: {len(labels)} boxes (world/objects), camera path of {len(cams)} frames "
                 "(world/camera), read back with rerun.chunk.RrdReader", fontsize=10)
    for k, im in enumerate(images[:6]):
        sub = fig.add_axes([0.01 + k * 0.165, 0.01, 0.155, 0.2])
        sub.imshow(im)
        sub.set_axis_off()
        sub.set_title(f"world/camera/rgb, frame {k}", fontsize=7)
    fig.savefig(args.output)
    print(f"{args.output}: {len(labels)} boxes, {len(cams)} cameras, {len(images)} images")


if __name__ == "__main__":
    main()

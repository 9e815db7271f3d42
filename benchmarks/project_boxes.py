"""Draw a map's boxes projected into frames of a recording, to look at a real map.

    python benchmarks/project_boxes.py MAP.h5 RECORDING -o out.png [--frames 0,50,100,150] [--cols 2] [--ids 3,7]
        [-r KEY=VALUE]...   (reader options, as for ltc ingest: -r intrinsics=518,519,325.5,253.5)

Without --frames, four frames spread evenly over the recording (all of them when it has fewer);
an index past the end means the last frame, and each frame is drawn once.

Each active object is drawn as its 12 box edges with ``id class``; vertices behind the camera are
skipped. The map's up rotation is applied to the recording's poses, as ingest does.
"""

from __future__ import annotations

import argparse
import sys
import zlib
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from ltc_cli.geometry.boxes import box_corners  # noqa: E402
from ltc_cli.geometry.camera import invert_pose, project, transform  # noqa: E402
from ltc_cli.map.model import ACTIVE, top_class  # noqa: E402
from ltc_cli.map.store import load_map  # noqa: E402
from ltc_cli.cli import reader_options  # noqa: E402
from ltc_cli.recordings.open import open_recording  # noqa: E402

EDGES = [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4), (0, 4), (1, 5), (2, 6), (3, 7)]


def colour(name: str):
    # crc32, not hash(): str hashes change from run to run, and a class keeps its colour across pictures.
    h = (zlib.crc32(name.encode()) * 2654435761) % 180
    hsv = np.uint8([[[h, 220, 255]]])
    return tuple(int(c) for c in cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)[0, 0])


def draw(smap, frame, T_up, ids=None):
    img = frame.rgb[..., ::-1].copy() if frame.rgb is not None else cv2.imread(frame.rgb_path)
    T_map_camera = T_up @ frame.T_world_camera
    T_camera_map = invert_pose(T_map_camera)
    t = smap.objects
    for row in np.flatnonzero(t.status == ACTIVE):
        if ids and row + 1 not in ids:
            continue
        name = smap.classes[int(top_class(t.scores[row]))]
        pts = transform(T_camera_map, box_corners(t.center[row], t.yaw[row], t.size[row]))
        u, v, z = project(pts, frame.intrinsics)
        col = colour(name)
        for a, b in EDGES:
            if z[a] > 0.05 and z[b] > 0.05:
                cv2.line(img, (int(u[a]), int(v[a])), (int(u[b]), int(v[b])), col, 2, cv2.LINE_AA)
        if (z > 0.05).all():
            k = int(np.argmin(v))
            cv2.putText(img, f"{row + 1} {name}", (int(u[k]), max(12, int(v[k]) - 4)), cv2.FONT_HERSHEY_SIMPLEX,
                        0.5, col, 1, cv2.LINE_AA)
    cv2.putText(img, f"frame {frame.key}", (8, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (255, 255, 255), 2)
    return img


def frame_indices(spec: str | None, count: int, default_count: int = 4) -> list[int]:
    """The frames to draw, in order and each once: ``spec``'s comma-separated indices (past the end:
    the last frame), or ``default_count`` spread evenly from the first frame to the last."""
    if spec:
        wanted = [min(int(x), count - 1) for x in spec.split(",") if x.strip()]
    else:
        wanted = np.linspace(0, count - 1, min(default_count, count)).round().astype(int).tolist()
    return list(dict.fromkeys(wanted))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("map")
    ap.add_argument("recording")
    ap.add_argument("-o", "--output", required=True)
    ap.add_argument("--frames", default=None, help="frame indices, comma-separated (default: four spread evenly)")
    ap.add_argument("--cols", type=int, default=2)
    ap.add_argument("--scale", type=float, default=0.6)
    ap.add_argument("--ids", default="", help="only these object ids (comma-separated; default all)")
    ap.add_argument("-r", "--reader-option", action="append", default=[], metavar="KEY=VALUE",
                    help="a reader option, as for ltc ingest (e.g. -r intrinsics=518,519,325.5,253.5)")
    args = ap.parse_args()
    smap = load_map(args.map)
    rec = open_recording(args.recording, options=reader_options(args.reader_option))
    T_up = np.eye(4)
    T_up[:3, :3] = smap.up_rotation
    tiles = []
    for i in frame_indices(args.frames, len(rec.frames)):
        frame = rec.frames[i].load()
        img = draw(smap, frame, T_up, {int(x) for x in args.ids.split(",") if x})
        tiles.append(cv2.resize(img, None, fx=args.scale, fy=args.scale, interpolation=cv2.INTER_AREA))
    while len(tiles) % args.cols:
        tiles.append(np.zeros_like(tiles[0]))
    rows = [np.hstack(tiles[r:r + args.cols]) for r in range(0, len(tiles), args.cols)]
    cv2.imwrite(args.output, np.vstack(rows))


if __name__ == "__main__":
    main()

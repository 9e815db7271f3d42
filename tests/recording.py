"""Write small ltc-recording/1 folders from the analytic scene of tests/scene.py."""

from pathlib import Path

import numpy as np

from ltc_cli.recordings.writer import RecordingWriter
from tests.scene import INTR, T_world_camera, render

CLASSES = ["chair", "table", "tv"]
# (x0, x1, y0, y1, z0, z1), class index: a table, a chair and a tv on the wall 4 m ahead.
OBJECTS = [
    ((3.0, 3.8, -1.0, 1.0, 0.0, 0.75), 1),
    ((2.0, 2.5, 1.3, 1.8, 0.0, 0.9), 0),
    ((3.9, 3.95, -2.2, -1.4, 1.0, 1.5), 2),
]


def write_recording(root, objects=OBJECTS, cam_ys=(1.5, 0.75, 0.0, -0.75, -1.5), wall_x=4.0):
    meta = {
        "format": "ltc-recording/1",
        "camera": {"width": INTR.width, "height": INTR.height, "fx": INTR.fx, "fy": INTR.fy,
                   "cx": INTR.cx, "cy": INTR.cy},
        "depth": {"scale": 1000.0, "min": 0.3, "max": 6.0},
        "classes": CLASSES,
    }
    writer = RecordingWriter(root, meta)
    for i, cam_y in enumerate(cam_ys):
        depth, masks = render([o for o, _ in objects], wall_x=wall_x, cam_y=cam_y)
        gray = (np.clip(depth / 5.0, 0, 1) * 255).astype(np.uint8)
        instances = [{"class": CLASSES[cls], "score": 0.9, "mask": mask}
                     for (box, cls), mask in zip(objects, masks) if mask.sum() > 200]
        writer.write_frame(f"{i:06d}", T_world_camera(cam_y=cam_y), np.stack([gray] * 3, -1),
                           np.round(depth * 1000).astype(np.uint16), instances=instances)
    writer.close()
    return Path(root)

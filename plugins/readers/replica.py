"""Replica as NICE-SLAM distributes it, and Co-SLAM, SplaTAM and others after it:

```
Replica/cam_params.json           {"camera": {"w", "h", "fx", "fy", "cx", "cy", "scale"}}
Replica/<scene>/results/frame%06d.jpg, depth%06d.png    16-bit, metres = value / scale (6553.5)
Replica/<scene>/traj.txt          a 4x4 camera-to-world matrix per line, row-major (OpenCV axes)
```

``ltc ingest Replica/room0 --map room0.h5`` reads it with no option: the camera and depth scale
come from ``cam_params.json`` in the scene's folder or the one above it (the reader options
``intrinsics`` and ``depth_scale`` override them). It is the plain-folder reader (:mod:`.folder`)
with the layout's names; frames pair with their depth image by number.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

from ltc_cli.errors import RecordingError
from ltc_cli.types import Recording
from ltc_plugins.readers.common import CLASSES_OPTION, intrinsics_option, open_folder, options_schema
from ltc_plugins.readers.folder import FolderReader

CAM_PARAMS = "cam_params.json"
DEPTH_SCALE = 6553.5
OPTIONS_SCHEMA = options_schema(DEPTH_SCALE, "estimate", classes=CLASSES_OPTION)


def camera_params(folder: Path) -> dict | None:
    """{"camera": (fx, fy, cx, cy), "size": (w, h), "scale", "path"} from cam_params.json in the scene's
    folder or its parent; None when there is none."""
    path = next((d / CAM_PARAMS for d in (folder, folder.parent) if (d / CAM_PARAMS).is_file()), None)
    if path is None:
        return None
    try:
        cam = json.loads(path.read_text(encoding="utf-8"))["camera"]
        out = {"camera": tuple(float(cam[k]) for k in ("fx", "fy", "cx", "cy")),
               "size": (int(cam["w"]), int(cam["h"])), "scale": float(cam.get("scale", DEPTH_SCALE)), "path": path}
    except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError) as exc:
        raise RecordingError(f"not Replica's camera file ({{\"camera\": {{w, h, fx, fy, cx, cy, scale}}}}; "
                             f"{type(exc).__name__}: {exc})", path) from None
    if not out["scale"] > 0:
        raise RecordingError(f"the depth scale must be positive, got {out['scale']}", path)
    return out


class ReplicaReader:
    """A Replica scene folder (``results/`` and ``traj.txt``), as NICE-SLAM distributes it."""

    name = "replica"
    OPTIONS_SCHEMA = OPTIONS_SCHEMA

    def sniff(self, path) -> bool:
        try:
            p = Path(path)
            return ((p / "traj.txt").is_file() and (p / "results").is_dir()
                    and next((p / "results").glob("frame*.jpg"), None) is not None)
        except OSError:
            return False

    def open(self, path, options: dict | None = None) -> Recording:
        folder, opts = open_folder(path, options, OPTIONS_SCHEMA, self.name)
        params = camera_params(folder)
        given_camera = camera = intrinsics_option(opts)
        if camera is None:
            if params is None:
                raise RecordingError(f"no {CAM_PARAMS} in the scene's folder or the one above it: give the camera "
                                     "(ltc ingest ... -r intrinsics=FX,FY,CX,CY)", folder)
            camera = params["camera"]
        given_scale = (options or {}).get("depth_scale")
        scale = opts["depth_scale"] if given_scale is not None or params is None else params["scale"]
        folder_opts = {"color": "results/frame*.jpg", "depth": "results/depth*.png", "poses": "traj.txt",
                       "intrinsics": list(camera), "depth_scale": scale, "up": opts["up"]}
        if opts.get("classes") is not None:
            folder_opts["classes"] = opts["classes"]
        rec = FolderReader().open(folder, folder_opts)
        size = (rec.intrinsics.width, rec.intrinsics.height)
        if params is not None and given_camera is None and params["size"] != size:
            raise RecordingError(f"the camera is {params['size'][0]}x{params['size'][1]}, the depth images "
                                 f"{size[0]}x{size[1]}", params["path"])
        return replace(rec, format=self.name, meta={**rec.meta, "reader": self.name})

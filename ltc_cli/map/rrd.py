"""A map (and optionally a recording) as a Rerun recording, to look at in 3D: ``ltc export --format
rrd`` writes it to a ``.rrd`` file, ``ltc view`` sends it to the Rerun viewer.

rerun-sdk is large (~0.5 GB installed), so it is the optional extra ``ltc[viz]``; without it every
entry point raises :class:`VizMissingError` with the one line that says how to get it.

What is logged (map frame: metres, z up, ``RIGHT_HAND_Z_UP``):

- ``world/objects``: the active objects as ``Boxes3D`` (centre, half sizes, yaw about z), labelled
  ``class #id``, coloured by class (an ``AnnotationContext`` names each class id); static.
- ``world/removed``: objects that maintenance removed, as grey boxes labelled with their removal;
  static, so they can be shown or hidden in the viewer.
- with a recording, on the timeline ``frame`` (and ``time`` when the reader gives stamps): the
  camera ``world/camera`` (``Transform3D`` of T_map_camera and a ``Pinhole`` with the recording's
  intrinsics, OpenCV axes), its colour image (JPEG-compressed) and depth image; the whole camera
  path as ``world/camera_path`` (static).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ltc_cli.errors import LtcError, FrameError
from ltc_cli.fileio import atomic_target
from ltc_cli.map.model import REMOVED, SemanticMap
from ltc_cli.map.query import classify, removal_events
from ltc_cli.text import SkippedFrames

INSTALL_HINT = "rerun-sdk is not installed: pip install 'ltc[viz]' (or pip install rerun-sdk)"
APPLICATION_ID = "ltc"


class VizMissingError(LtcError):
    """The optional extra ltc[viz] (rerun-sdk) is not installed."""


def require_rerun():
    """The ``rerun`` module, or VizMissingError with how to install it."""
    try:
        import rerun
    except ImportError:
        raise VizMissingError(INSTALL_HINT) from None
    return rerun


def _colours_u8(names) -> dict[str, list[int]]:
    from ltc_cli.map.render import class_colours

    return {n: [int(round(255 * v)) for v in rgb] for n, rgb in class_colours(names).items()}


def log_map(rec, smap: SemanticMap) -> int:
    """Log the map's objects (static); returns how many active objects were logged."""
    rr = require_rerun()
    t = smap.objects
    cls_idx, conf = classify(smap)
    colours = _colours_u8(smap.classes)
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    rec.log("world", rr.AnnotationContext([
        rr.AnnotationInfo(id=i, label=name, color=colours[name]) for i, name in enumerate(smap.classes)
    ]), static=True)  # fmt: skip
    rows = smap.active_rows()

    def boxes(sel, labels, colour=None):
        return rr.Boxes3D(
            centers=t.center[sel], half_sizes=t.size[sel] / 2.0,
            rotation_axis_angles=[rr.RotationAxisAngle(axis=[0.0, 0.0, 1.0], radians=float(y)) for y in t.yaw[sel]],
            labels=labels, class_ids=cls_idx[sel], colors=colour, show_labels=True,
        )  # fmt: skip

    labels = [f"{smap.classes[int(cls_idx[r])]} #{r + 1} ({conf[r]:.2f})" for r in rows]
    rec.log("world/objects", boxes(rows, labels), static=True)
    gone = np.flatnonzero(t.status == REMOVED)
    if gone.size:
        ev = removal_events(smap)
        labels = [f"{smap.classes[int(cls_idx[r])]} #{r + 1} removed in session {ev[r + 1].session}"
                  if r + 1 in ev else f"{smap.classes[int(cls_idx[r])]} #{r + 1} removed" for r in gone]
        rec.log("world/removed", boxes(gone, labels, [150, 150, 150]), static=True)
    return int(len(rows))


def log_recording(rec, recording, T_map_world: np.ndarray, every: int = 1, images: bool = True,
                  skips: SkippedFrames | None = None) -> int:
    """Log a recording's camera path and, every ``every`` frames, its camera and images on the
    ``frame`` timeline. Frames that cannot be read are skipped, and counted in ``skips`` (which
    warns of ten of each kind of reason). Returns how many frames were logged."""
    rr = require_rerun()
    intr = recording.intrinsics
    rec.log("world/camera", rr.Pinhole(image_from_camera=intr.K, resolution=[intr.width, intr.height],
                                       camera_xyz=rr.ViewCoordinates.RDF, image_plane_distance=0.3), static=True)
    path, done = [], 0
    for ref in recording.frames[::max(1, int(every))]:
        try:
            frame = ref.load()
        except FrameError as exc:
            if skips is not None:
                skips.skip(ref.key, exc)
            continue
        T = T_map_world @ frame.T_world_camera
        path.append(T[:3, 3])
        rec.set_time("frame", sequence=int(ref.index))
        if "timestamp" in frame.extra:
            rec.set_time("time", timestamp=float(frame.extra["timestamp"]))
        rec.log("world/camera", rr.Transform3D(translation=T[:3, 3], mat3x3=T[:3, :3]))
        if images:
            if frame.rgb is not None:
                rec.log("world/camera/rgb", rr.Image(frame.rgb).compress(jpeg_quality=80))
            rec.log("world/camera/depth", rr.DepthImage(frame.depth_m, meter=1.0))
        done += 1
    if path:
        rec.log("world/camera_path", rr.LineStrips3D([np.asarray(path)], colors=[[230, 60, 60]]), static=True)
    return done


def new_stream(name: str):
    rr = require_rerun()
    return rr.RecordingStream(APPLICATION_ID, recording_id=name)


def write_rrd(path, smap: SemanticMap, recording=None, T_map_world=None, every: int = 1, images: bool = True,
              skips: SkippedFrames | None = None) -> dict:
    """Write the map (and a recording) to an .rrd file, atomically. Returns what was logged."""
    path = Path(path)
    stream = new_stream(path.stem)
    try:
        with atomic_target(path) as tmp:
            stream.save(str(tmp))
            n_obj = log_map(stream, smap)
            n_frames = 0
            if recording is not None:
                n_frames = log_recording(stream, recording, np.eye(4) if T_map_world is None else T_map_world,
                                         every, images, skips)
            stream.flush()
            stream.disconnect()  # closes the file before it replaces the target
    except OSError as exc:
        raise LtcError(f"cannot write the .rrd file ({exc.strerror or exc})", path) from None
    return {"objects": n_obj, "frames": n_frames}

"""``simulate()``: build the house, drive the path every lap, change the house between laps, and
write each lap as an ``ltc-recording/1`` folder."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ltc_cli.errors import ConfigError, LtcError
from ltc_cli.pipeline.modeling import pixel_scale, scaled_px
from ltc_cli.recordings.writer import RecordingWriter
from ltc_cli.tools.simulate.changes import change_house
from ltc_cli.tools.simulate.detector import detect
from ltc_cli.tools.simulate.house import House
from ltc_cli.tools.simulate.extras import LapExtras
from ltc_cli.tools.simulate.options import (
    CLASSES, FRAMES_PER_ROOM, SCENES, check_int, check_options, recorded_options,
)
from ltc_cli.tools.simulate.path import camera_path
from ltc_cli.tools.simulate.phantoms import PHANTOM_BASE, place_phantoms
from ltc_cli.tools.simulate.raycast import Renderer
from ltc_cli.tools.simulate.sensor import DEPTH_SCALE, depth_image, rgb_image

RECORDING_DEPTH_RANGE = (0.3, 6.0)  # the range written to recording.yaml (reliable readings)


class OutputExistsError(LtcError):
    """A lap folder to write already exists and is not empty."""


def simulate(outdir, scene: str = "small", laps: int = 2, seed: int = 0, width: int = 640,
             height: int = 480, profile: str = "benign", progress=None, **options) -> dict:
    """Write a synthetic house recording, one ``ltc-recording/1`` folder per lap.

    outdir: the folder to write ``lap1``, ``lap2``, ... into (created as needed); a lap folder that
        exists and is not empty is refused (:class:`OutputExistsError`) before anything is written.
    scene: "tiny" (one room, 7 objects, 12 frames per lap: for tests), "small" (2 rooms),
        "medium" (4 rooms) or "large" (6 rooms).
    laps: how many laps (1-100); lap 1 is the original house, each later lap changes the previous.
    seed: any integer >= 0; the same arguments give byte-identical files.
    width, height: image size; the intrinsics are those of a Kinect-like camera (fx = fy = 525 at
        640 px wide, scaled with the width; principal point in the middle).
    profile: "benign" (the default here: independent per-frame detector noise, exact poses) or
        "realistic" (the real failure modes: pose drift, per-class and correlated misses,
        systematic mislabels, recurring phantoms, CNN-like masks, depth holes and flying pixels,
        sizes varying within a class, people walking through); see ``PROFILES``.
    options: see ``DEFAULTS`` (detector noise rates, depth noise, lap changes, path density, the
        realistic failure modes one by one); they override the profile's values.
    progress: called as ``progress(done, total)`` after each frame written (frames of all laps).

    Returns a summary: {"outdir", "scene", "seed", "width", "height", "classes", "frames_per_lap",
    "objects_per_lap", "changes" (per lap), "laps": [{"lap", "path", "frames", "objects",
    "changes"}], "bytes"}. Raises :class:`ltc_cli.errors.ConfigError` on bad arguments.
    """
    if scene not in SCENES:
        raise ConfigError(f"simulate: unknown scene {scene!r} (choose from {', '.join(SCENES)})")
    laps = check_int("laps", laps, 1, 100)
    seed = check_int("seed", seed, 0, 2**63 - 1)
    width = check_int("width", width, 16, 4096)
    height = check_int("height", height, 16, 4096)
    opts = check_options(options, profile)
    frames_per_room = opts["frames_per_room"] or FRAMES_PER_ROOM[scene]
    min_pixels = opts["min_pixels"] if opts["min_pixels"] is not None else max(20, int(round(5e-4 * width * height)))

    outdir = Path(outdir)
    lap_dirs = [outdir / f"lap{k}" for k in range(1, laps + 1)]
    for d in lap_dirs:
        if d.exists() and (not d.is_dir() or any(d.iterdir())):
            raise OutputExistsError("exists and is not empty; refusing to overwrite it", path=d)

    fx = fy = 525.0 * width / 640.0
    cx, cy = (width - 1) / 2.0, (height - 1) / 2.0
    renderer = Renderer(width, height, fx, fy, cx, cy)

    house = House(scene, np.random.default_rng([seed, 0x5CE7E]), np.random.default_rng([seed, 0x512E]),
                  opts["size_variation"])
    poses = camera_path(house, np.random.default_rng([seed, 0x9A7]), frames_per_room, opts["transit_step"],
                        opts["camera_height"], opts["camera_pitch_deg"])
    phantoms = place_phantoms(house, np.random.default_rng([seed, 0xFA47]), opts["phantoms_per_room"])
    classes = list(CLASSES) + (["person"] if opts["people_per_room"] > 0 else [])
    sim_options = recorded_options(opts)
    sim_options["frames_per_room"] = frames_per_room
    sim_options["min_pixels"] = min_pixels
    # A CNN's mask bleeds by a share of the image (YOLOv8-seg's masks come from an 80 x 80 grid
    # over its input): bleed_px is for 640 x 480 and grows with a larger image, as ltc's pixel
    # settings do (modeling.scale_pixels); the recording states the option as given.
    opts = {**opts, "bleed_px": bleed_at(opts["bleed_px"], width, height)}
    simulator = {"scene": scene, "seed": seed}
    if profile != "benign":  # (absent: benign, as every recording made before profiles existed)
        simulator["profile"] = profile

    summary = {
        "outdir": str(outdir), "scene": scene, "seed": seed, "width": width, "height": height,
        "classes": classes, "frames_per_lap": len(poses), "objects_per_lap": [], "changes": [],
        "laps": [], "bytes": 0,
    }
    for lap, lap_dir in enumerate(lap_dirs, start=1):
        if lap == 1:
            changes = {"moved": [], "removed": [], "added": []}
        else:
            changes = change_house(house, np.random.default_rng([seed, lap, 0xC4A9E]), opts["moved_fraction"],
                                   opts["removed_fraction"], opts["added_fraction"])
        meta = {
            "format": "ltc-recording/1",
            "name": f"ltc simulate: {scene} house, seed {seed}, lap {lap} of {laps}",
            "camera": {"width": width, "height": height, "fx": float(fx), "fy": float(fy),
                       "cx": float(cx), "cy": float(cy)},
            "depth": {"scale": DEPTH_SCALE, "min": RECORDING_DEPTH_RANGE[0], "max": RECORDING_DEPTH_RANGE[1]},
            "up": [0.0, 0.0, 1.0],
            "classes": list(classes),
            "simulator": {**simulator, "lap": lap, "laps": laps, "options": sim_options},
        }
        extras = LapExtras.make(house, poses, phantoms, opts, seed, lap)
        done = (lap - 1) * len(poses)

        def frame_written(i, done=done):
            if progress is not None:
                progress(done + i + 1, laps * len(poses))

        try:
            nbytes = write_lap(RecordingWriter(lap_dir, meta), house, poses, renderer, opts, min_pixels,
                               classes, seed, lap, changes, extras, frame_written)
        except OSError as exc:
            raise LtcError(f"cannot write: {exc.strerror or exc}", path=exc.filename or lap_dir) from exc
        summary["objects_per_lap"].append(len(house.objects))
        summary["changes"].append(changes)
        summary["laps"].append({"lap": lap, "path": str(lap_dir), "frames": len(poses),
                                "objects": len(house.objects), "changes": changes})
        summary["bytes"] += nbytes
    return summary


def write_lap(writer: RecordingWriter, house: House, poses, renderer: Renderer, opts, min_pixels, classes,
              seed, lap, changes, extras: LapExtras, frame_written=None) -> int:
    """Render, detect and write every frame of one lap, then its ground truth; returns its bytes.
    The images are rendered from the true poses; poses.txt gets the localiser's (extras)."""
    centers, yaws, sizes, colors, owners = extras.static_primitives(house)
    classes_of = {oid: o.cls for oid, o in house.objects.items()}
    classes_of.update(extras.classes_of())
    seen_pixels = {oid: 0 for oid in house.objects}
    seen_frames = {oid: 0 for oid in house.objects}
    for i, T in enumerate(poses):
        fid = f"{i:06d}"
        rng_det, rng_depth, rng_rgb, rng_sensor, rng_views = (
            np.random.default_rng(s) for s in np.random.SeedSequence([seed, lap, 0xF4A3E, i]).spawn(5))
        prims = extras.frame_primitives(i, T, (centers, yaws, sizes, colors, owners))
        zbuf, prim, face, stats = renderer.render(T, prims[0], prims[1], prims[2], prims[4])
        hit = prim >= 0
        inst = np.where(hit, prims[4][np.where(hit, prim, 0)], 0)
        # Phantoms and people are seen and detected but are not ground-truth objects.
        annotations = np.where(inst < PHANTOM_BASE, inst, 0).astype(np.uint16)
        depth_mm = depth_image(rng_depth, zbuf, hit, opts, extras.dropout(prim, prims), rng_sensor)
        rgb = rgb_image(rng_rgb, prim, face, prims[1], prims[3], opts)
        ids, counts = np.unique(annotations[annotations > 0], return_counts=True)
        for oid, n in zip(ids.tolist(), counts.tolist()):
            seen_pixels[oid] += n
            seen_frames[oid] += 1
        views = None if extras.views is None else extras.views.frame(i, T, rng_views)
        dets = detect(rng_det, inst, depth_mm.astype(np.float64) / DEPTH_SCALE, stats, classes_of, classes,
                      opts, min_pixels, views)
        instances = [{
            "class": cls,
            "score": round(score, 4),
            # Classes absent from the vector have probability 0.
            "scores": {c: round(v, 4) for c, v in scores.items()},
            "mask": mask,
        } for cls, score, scores, mask in dets]
        writer.write_frame(fid, extras.written_poses[i], rgb, depth_mm, annotations=annotations,
                           instances=instances, detector="ltc-simulate")
        if frame_written is not None:
            frame_written(i)

    objects = []
    for oid, o in house.objects.items():
        center, yaw, size = o.box()
        objects.append({
            "id": oid, "class": o.cls, "center": [float(v) for v in center], "yaw": float(yaw),
            "size": [float(v) for v in size],
            "seen_pixels": int(seen_pixels[oid]), "seen_frames": int(seen_frames[oid]),
            "room": house.rooms[o.room].kind,
        })
    writer.write_ground_truth(objects, lap, changes)
    return writer.close()


def bleed_at(bleed_px: int, width: int, height: int) -> int:
    """The simulated mask bleed in an image of this size: ``bleed_px`` is for 640 x 480 and grows
    with a larger image's longer side, rounded half up (:func:`~ltc_cli.pipeline.modeling.scaled_px`)."""
    return scaled_px(int(bleed_px), pixel_scale((int(height), int(width))))

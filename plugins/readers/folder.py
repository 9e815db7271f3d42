"""Plain-folder reader: colour and depth images and a pose file, with the camera given as reader
options (``ltc ingest FOLDER -r intrinsics=FX,FY,CX,CY``), so data as a robot or a SLAM system left
it maps with one command and without writing a recording.yaml into it (the folder may be read-only).

Layout (every name can be changed with an option):

```
color/<stem>.png|jpg     (or colour/, rgb/, image/, images/)
depth/<stem>.png|pgm|tif 16-bit, metres = value / depth_scale (default 1000: millimetres); 0 = none
pose.txt                 (or poses.txt, trajectory.txt, trajectory.log): T_world_camera, OpenCV
                         camera axes, one line per frame, any of
                           tx ty tz qx qy qz qw          line N = the N-th colour image (natural order)
                           stem tx ty tz qx qy qz qw     the frame named by its first field
                           12 or 16 numbers              a 3x4 (KITTI) or 4x4 matrix, row-major, by order
                         or five lines per frame, as Open3D and the Redwood datasets write
                         trajectory.log: three numbers (metadata), then the 4x4 matrix's four rows
```

The camera is the reader option ``intrinsics``, else Open3D's ``camera_intrinsic.json`` in the
folder (as its reconstruction system keeps it beside ``color/``, ``depth/`` and
``scene/trajectory.log``, which is found too).

``color`` and ``depth`` may end in a file pattern (``results/frame*.jpg``, ``results/depth*.png``:
Replica as NICE-SLAM and its successors distribute it, both kinds in one folder). When no colour
image has a depth image of its name, each pairs with the depth image of its number (the last run
of digits in the name: frame000012 with depth000012).
"""

from __future__ import annotations

import json
import re
from fnmatch import fnmatch
from pathlib import Path

import numpy as np

from ltc_cli import hookimpl
from ltc_cli.errors import FrameError, RecordingError
from ltc_cli.types import Recording
from ltc_plugins.readers.common import (
    CLASSES_OPTION, FrameSource, ImageFormat, checked_matrix_pose, first_existing, first_size, frame_refs, identity,
    intrinsics_option, make_intrinsics, open_folder, options_schema, quaternion_pose, read_bytes,
    up_option,
)  # fmt: skip

COLOR_DIRS = ("color", "colour", "rgb", "image", "images")
POSE_FILES = ("pose.txt", "poses.txt", "trajectory.txt", "trajectory.log", "scene/trajectory.log")
INTRINSIC_FILES = ("camera_intrinsic.json", "intrinsic.json")
COLOR_EXT = (".png", ".jpg", ".jpeg")
DEPTH_EXT = (".png", ".pgm", ".tif", ".tiff")

_NAME = {"type": "string", "minLength": 1}
OPTIONS_SCHEMA = options_schema(
    1000.0,
    "estimate",
    color={**_NAME, "description": f"colour image folder, or folder/pattern such as results/frame*.jpg (default: "
           f"the first of {', '.join(COLOR_DIRS)})"},
    depth={**_NAME, "default": "depth", "description": "depth image folder, or folder/pattern such as "
           "results/depth*.png"},
    poses={**_NAME, "description": f"pose file (default: the first of {', '.join(POSE_FILES)})"},
    classes=CLASSES_OPTION,
)  # fmt: skip

_NUMBER_RUN = re.compile(r"(\d+)")


def natural_key(stem: str) -> tuple:
    """Sort key that orders "2" before "10" and "frame-2" before "frame-10"."""
    return tuple(int(p) if p.isdigit() else p for p in _NUMBER_RUN.split(stem))


def _images(folder: Path, extensions: tuple[str, ...], pattern: str | None = None) -> dict[str, Path]:
    """{stem: path} of the images in a folder whose names match ``pattern`` (None: any), of the
    given extensions (of two with one stem, the earlier extension wins)."""
    try:
        paths = [p for p in folder.iterdir() if p.suffix.lower() in extensions and p.is_file()
                 and (pattern is None or fnmatch(p.name, pattern))]
    except OSError:
        return {}
    paths.sort(key=lambda p: (p.stem, extensions.index(p.suffix.lower())))
    found: dict[str, Path] = {}
    for p in paths:
        found.setdefault(p.stem, p)
    return found


def open3d_intrinsics(folder: Path) -> tuple[tuple[float, float, float, float], tuple[int, int], Path] | None:
    """((fx, fy, cx, cy), (width, height), file) from Open3D's PinholeCameraIntrinsic JSON in the
    folder (``intrinsic_matrix``: the 3x3 matrix's 9 entries column by column, as Eigen stores
    it); None when there is none."""
    path = next((folder / f for f in INTRINSIC_FILES if (folder / f).is_file()), None)
    if path is None:
        return None
    try:
        doc = json.loads(path.read_text(encoding="utf-8-sig"))
        K = np.array(doc["intrinsic_matrix"], dtype=np.float64).reshape(3, 3).T  # column-major
        size = (int(doc["width"]), int(doc["height"]))
    except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError) as exc:
        raise RecordingError(f"not an Open3D camera intrinsic file (width, height, intrinsic_matrix: 9 numbers; "
                             f"{type(exc).__name__}: {exc})", path) from None
    camera = (K[0, 0], K[1, 1], K[0, 2], K[1, 2])
    if not (np.isfinite(camera).all() and camera[0] > 0 and camera[1] > 0):
        raise RecordingError(f"the camera's fx, fy, cx, cy must be finite and fx, fy positive, got {camera}", path)
    return tuple(float(v) for v in camera), size, path


def split_pattern(name: str | None) -> tuple[str | None, str | None]:
    """("results", "frame*.jpg") from "results/frame*.jpg"; (name, None) when it has no pattern."""
    if name is None or not any(c in Path(name).name for c in "*?["):
        return name, None
    return str(Path(name).parent), Path(name).name


def paired_by_number(colors: dict[str, Path], depths: dict[str, Path], where: Path) -> dict[str, Path]:
    """``depths`` keyed by the colour image of the same number (the last run of digits in the
    name), for layouts whose colour and depth names differ (frame000012.jpg, depth000012.png)."""
    def number(stem: str) -> int | None:
        runs = _NUMBER_RUN.findall(stem)
        return int(runs[-1]) if runs else None

    by_number: dict[int, Path] = {}
    for stem, path in depths.items():
        n = number(stem)
        if n is not None and by_number.setdefault(n, path) is not path:
            raise RecordingError(f"two depth images are numbered {n} ({by_number[n].name}, {path.name}): "
                                 "pair them by name, or narrow the reader option depth to one of them", where)
    return {stem: by_number[number(stem)] for stem in colors if number(stem) in by_number}


def _color_dir(folder: Path, name: str | None) -> Path | None:
    if name is not None:
        return folder / name
    return next((folder / d for d in COLOR_DIRS if (folder / d).is_dir()), None)


def _pose_file(folder: Path, name: str | None) -> Path | None:
    if name is not None:
        return folder / name
    return next((folder / f for f in POSE_FILES if (folder / f).is_file()), None)


def _same_stem(a: str, b: str) -> bool:
    """"1" names frame "000001" too (pose files often drop the images' zero padding)."""
    return a == b or (a.isdigit() and b.isdigit() and int(a) == int(b))


def read_pose_lines(path: Path, stems: list[str]) -> dict[str, tuple[str, list[str]]]:
    """{stem: (where, fields)} from a pose file (see the module docstring for the line forms)."""
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise RecordingError(f"cannot read the pose file ({exc})", path) from None
    rows = [(n, line.replace(",", " ").split()) for n, line in enumerate(text.splitlines(), 1)
            if line.strip() and not line.lstrip().startswith("#")]
    counts = {len(fields) for _, fields in rows}
    if not rows:
        raise RecordingError("the pose file has no poses", path)
    if counts == {3, 4}:
        rows = log_blocks(rows, path)
        counts = {16}
    if len(counts) != 1 or counts - {7, 8, 12, 16}:
        raise RecordingError(
            f"pose lines must all have 7 (tx ty tz qx qy qz qw), 8 (frame and those 7), 12 (3x4) or 16 (4x4) "
            f"fields; found {sorted(counts)}", path)
    if counts == {8}:
        out = {}
        for n, fields in rows:
            stem = next((s for s in stems if _same_stem(fields[0], s)), None)
            if stem is None:
                raise RecordingError(f"line {n}: no colour image is named {fields[0]!r}", path)
            out[stem] = (f"line {n}", fields[1:])
        return out
    if len(rows) != len(stems):
        raise RecordingError(
            f"{len(rows)} pose lines for {len(stems)} colour images: without frame names line N is the N-th "
            "image, so the counts must agree (or put each frame's name first on its line)", path)
    return {stem: (n if isinstance(n, str) else f"line {n}", fields) for stem, (n, fields) in zip(stems, rows)}


def log_blocks(rows: list, path: Path) -> list:
    """Open3D's / Redwood's trajectory.log: per frame, a line of three numbers (metadata) and the 4x4
    camera-to-world matrix's four rows; as ("lines a-b", the matrix's 16 fields) rows, one per frame."""
    shapes = [len(fields) for _, fields in rows]
    if len(rows) % 5 or any(shapes[k:k + 5] != [3, 4, 4, 4, 4] for k in range(0, len(rows), 5)):
        raise RecordingError("a trajectory.log gives each frame as a line of three numbers, then four lines of "
                             "four (the 4x4 matrix's rows)", path)
    return [(f"lines {rows[k][0]}-{rows[k + 4][0]}", [f for _, fields in rows[k + 1:k + 5] for f in fields])
            for k in range(0, len(rows), 5)]


def pose_of(path: Path, where: str, fields: list[str]):
    """pose(): T_world_camera (4, 4) of one pose line, checked when the frame loads."""
    def pose() -> np.ndarray:
        try:
            vals = np.array([float(f) for f in fields])
        except ValueError:
            raise FrameError(f"{where}: not a number in {' '.join(fields)!r}", path) from None
        if vals.size == 7:
            return quaternion_pose(vals, path, where)
        T = np.vstack([vals.reshape(-1, 4), [0.0, 0.0, 0.0, 1.0]]) if vals.size == 12 else vals.reshape(4, 4)
        return checked_matrix_pose(T, path)

    return pose


class FolderReader:
    """A plain folder of colour and depth images and a pose file; the camera comes from the
    reader option ``intrinsics`` (required), the depth unit from ``depth_scale`` (default 1000).

    The world's up is estimated by default (SLAM systems usually start their world at the first
    camera, which is not z-up); give ``up`` (e.g. ``z`` or ``-y``) when it is known.
    """

    name = "folder"
    OPTIONS_SCHEMA = OPTIONS_SCHEMA

    def sniff(self, path) -> bool:
        try:
            p = Path(path)
            # Folders with their own layout file belong to their own readers.
            if not p.is_dir() or any((p / f).exists() for f in ("recording.yaml", "rgb.txt", "intrinsic")):
                return False
            return (_color_dir(p, None) is not None and (p / "depth").is_dir()
                    and _pose_file(p, None) is not None)
        except OSError:
            return False

    def open(self, path, options: dict | None = None) -> Recording:
        folder, opts = open_folder(path, options, OPTIONS_SCHEMA, self.name)
        camera, from_file = intrinsics_option(opts), None
        if camera is None:
            from_file = open3d_intrinsics(folder)
            if from_file is None:
                raise RecordingError(
                    "a plain folder of images needs the camera: give the reader option intrinsics "
                    f"(ltc ingest ... -r intrinsics=FX,FY,CX,CY, in pixels), or put it in {INTRINSIC_FILES[0]}", folder)
            camera = from_file[0]
        color_name, color_glob = split_pattern(opts.get("color"))
        depth_name, depth_glob = split_pattern(opts["depth"])
        color_dir = _color_dir(folder, color_name)
        if color_dir is None or not color_dir.is_dir():
            tried = opts.get("color") or "/, ".join(COLOR_DIRS)
            raise RecordingError(f"no colour image folder ({tried}/); name it with the reader option color", folder)
        depth_dir = folder / depth_name
        if not depth_dir.is_dir():
            raise RecordingError("no depth image folder; name it with the reader option depth", depth_dir)
        pose_path = _pose_file(folder, opts.get("poses"))
        if pose_path is None or not pose_path.is_file():
            tried = opts.get("poses") or ", ".join(POSE_FILES)
            raise RecordingError(f"no pose file ({tried}); name it with the reader option poses", folder)

        colors = _images(color_dir, COLOR_EXT, color_glob)
        depths = _images(depth_dir, DEPTH_EXT, depth_glob)
        if depths and not set(colors) & set(depths):
            depths = paired_by_number(colors, depths, depth_dir)
        stems = sorted(colors, key=natural_key)
        if not stems:
            raise RecordingError(f"no colour images ({', '.join(COLOR_EXT)})", color_dir)
        poses = read_pose_lines(pose_path, stems)
        depth_scale = float(opts["depth_scale"])
        width, height = first_size((depths[s] for s in stems if s in depths), folder)
        if from_file is not None and from_file[1] != (width, height):
            raise RecordingError(f"the camera is {from_file[1][0]}x{from_file[1][1]}, the depth images "
                                 f"{width}x{height}", from_file[2])
        intr = make_intrinsics(width, height, camera, None)

        def missing_pose(stem: str):
            def pose():
                raise FrameError(f"frame {stem!r} has no pose line", pose_path)
            return pose

        sources = [
            FrameSource(
                key=stem,
                rgb_path=colors[stem],
                # A colour image without depth is listed, so its load() names the missing file.
                depth_path=depths.get(stem) or first_existing(*(depth_dir / f"{stem}{e}" for e in DEPTH_EXT)),
                pose=pose_of(pose_path, *poses[stem]) if stem in poses else missing_pose(stem),
            )
            for stem in stems
        ]
        # The pose file, the image names and the camera: the same folder read with another camera
        # is another recording.
        listing = "\n".join(f"{colors[s].name} {depths[s].name if s in depths else '-'}" for s in stems)
        camera_text = f"{camera} {depth_scale}"
        return Recording(
            path=str(folder),
            format="folder",
            identity=identity([(pose_path.name, read_bytes(pose_path)), ("images", listing.encode()),
                               ("camera", camera_text.encode())]),
            intrinsics=intr,
            frames=frame_refs(sources, ImageFormat(intr, depth_scale)),
            up=up_option(opts, self.name), classes=opts.get("classes"),
            meta={"reader": self.name, "depth_scale": depth_scale, "color": color_dir.name,
                  "depth": depth_dir.name, "poses": pose_path.name},
        )


@hookimpl
def register_readers(register):
    register(FolderReader.name, FolderReader())

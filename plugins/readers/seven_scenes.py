"""7-Scenes / 3DMatch reader: one folder of ``frame-NNNNNN.{color.png|color.jpg,depth.png,pose.txt}``."""

from __future__ import annotations

import re
from functools import partial
from pathlib import Path

from ltc_cli.errors import RecordingError
from ltc_cli.types import Recording
from ltc_plugins.readers.common import (
    FrameSource, ImageFormat, first_existing, first_size, frame_refs, identity, intrinsics_option,
    make_intrinsics, open_folder, options_schema, read_bytes, read_matrix_file, read_matrix_pose,
    up_option,
)  # fmt: skip

SEVEN_SCENES_DEFAULT = (585.0, 585.0, 320.0, 240.0)
OPTIONS_SCHEMA = options_schema(1000.0, "estimate")
_FRAME_POSE = re.compile(r"^(frame-\d+)\.pose\.txt$")


def _seven_scenes_frames(folder: Path) -> list[str]:
    """Frame stems ("frame-000000") of a folder, in numeric order."""
    try:
        names = [m.group(1) for p in folder.iterdir() if (m := _FRAME_POSE.match(p.name))]
    except OSError:
        return []
    return sorted(names, key=lambda s: (int(s.split("-")[1]), s))


def _seq_folders(folder: Path) -> list[Path]:
    try:
        return sorted(
            p for p in folder.iterdir()
            if p.is_dir() and p.name.startswith("seq") and _seven_scenes_frames(p)
        )  # fmt: skip
    except OSError:
        return []


class SevenScenesReader:
    """7-Scenes / 3DMatch: one folder of ``frame-NNNNNN.{color.png|color.jpg,depth.png,pose.txt}``.

    Depth is in millimetres (65535 = no reading in 7-Scenes, mapped to 0); poses are 4x4
    camera-to-world. ``camera-intrinsics.txt`` (3x3 K) is looked for in the folder and then in its
    parent (3DMatch keeps it beside the seq-XX folders); without it the 7-Scenes Kinect default
    (fx = fy = 585, cx = 320, cy = 240) applies. Sequences are never merged: each seq-XX folder is a
    recording of its own (their poses need not share a world frame).
    """

    name = "7scenes"
    OPTIONS_SCHEMA = OPTIONS_SCHEMA

    def sniff(self, path) -> bool:
        try:
            p = Path(path)
            # A scene folder holding seq-XX folders is claimed too, so open() can say which to give.
            return p.is_dir() and (bool(_seven_scenes_frames(p)) or bool(_seq_folders(p)))
        except OSError:
            return False

    def open(self, path, options: dict | None = None) -> Recording:
        folder, opts = open_folder(path, options, OPTIONS_SCHEMA, self.name)
        stems = _seven_scenes_frames(folder)
        if not stems:
            seqs = _seq_folders(folder)
            if seqs:
                raise RecordingError(
                    "this folder holds sequences, not frames; give one sequence folder per recording: "
                    + ", ".join(p.name for p in seqs),
                    folder,
                )
            raise RecordingError("no frame-NNNNNN.pose.txt files in the folder", folder)
        depth_scale = float(opts["depth_scale"])

        intr_file = next(
            (d / "camera-intrinsics.txt" for d in (folder, folder.parent)
             if (d / "camera-intrinsics.txt").is_file()),
            None,
        )  # fmt: skip
        if intr_file is not None:
            K = read_matrix_file(intr_file, "camera intrinsics")
            default_cam = (K[0, 0], K[1, 1], K[0, 2], K[1, 2])
        else:
            default_cam = SEVEN_SCENES_DEFAULT
        width, height = first_size((folder / f"{s}.depth.png" for s in stems), folder)
        intr = make_intrinsics(width, height, default_cam, intrinsics_option(opts))

        sources = [
            FrameSource(
                key=stem,
                rgb_path=first_existing(folder / f"{stem}.color.png", folder / f"{stem}.color.jpg"),
                depth_path=folder / f"{stem}.depth.png",
                pose=partial(read_matrix_pose, folder / f"{stem}.pose.txt"),
            )
            for stem in stems
        ]
        pose_files = [(f"{s}.pose.txt", read_bytes(folder / f"{s}.pose.txt")) for s in stems]
        meta_files = [(intr_file.name, read_bytes(intr_file))] if intr_file is not None else []
        return Recording(
            path=str(folder),
            format="7scenes",
            identity=identity(meta_files + pose_files),
            intrinsics=intr,
            frames=frame_refs(sources, ImageFormat(intr, depth_scale, invalid_raw=65535)),
            up=up_option(opts, self.name),
            meta={
                "reader": self.name,
                "depth_scale": depth_scale,
                "intrinsics_file": str(intr_file) if intr_file is not None else None,
            },
        )

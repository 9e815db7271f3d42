"""ScanNet export reader (SensReader output): color/, depth/, pose/, intrinsic/."""

from __future__ import annotations

from functools import partial
from pathlib import Path

from ltc_cli.errors import RecordingError
from ltc_cli.types import Recording
from ltc_plugins.readers.common import (
    FrameSource, ImageFormat, first_existing, first_size, frame_refs, identity, intrinsics_option,
    make_intrinsics, open_folder, options_schema, read_bytes, read_matrix_file, read_matrix_pose,
    up_option,
)  # fmt: skip

OPTIONS_SCHEMA = options_schema(1000.0, None)


def _numbered(folder: Path, ext: str) -> list[str]:
    """Stems of ``N.<ext>`` files in numeric order."""
    try:
        stems = [p.stem for p in folder.iterdir() if p.suffix == ext and p.stem.isdigit()]
    except OSError:
        return []
    return sorted(stems, key=int)


class ScanNetReader:
    """ScanNet export: ``color/N.jpg``, ``depth/N.png`` (mm), ``pose/N.txt`` (4x4 camera-to-world),
    ``intrinsic/intrinsic_depth.txt`` (4x4).

    Frames are at the depth camera's resolution and intrinsics; colour (often 1296x968) is resized to
    it. Frames whose pose is ``-inf`` (lost tracking) raise FrameError when loaded. ScanNet worlds are
    z-up, so ``up`` defaults to None.
    """

    name = "scannet"
    OPTIONS_SCHEMA = OPTIONS_SCHEMA

    def sniff(self, path) -> bool:
        try:
            p = Path(path)
            return all((p / d).is_dir() for d in ("color", "depth", "pose")) and (
                (p / "intrinsic").is_dir()
            )
        except OSError:
            return False

    def open(self, path, options: dict | None = None) -> Recording:
        folder, opts = open_folder(path, options, OPTIONS_SCHEMA, self.name)
        for d in ("color", "depth", "pose"):
            if not (folder / d).is_dir():
                raise RecordingError(f"ScanNet export has no {d}/ folder", folder)
        depth_scale = float(opts["depth_scale"])
        override = intrinsics_option(opts)
        intr_file = folder / "intrinsic" / "intrinsic_depth.txt"
        meta_files = []
        if intr_file.is_file():
            K = read_matrix_file(intr_file, "depth intrinsics")
            default_cam = (K[0, 0], K[1, 1], K[0, 2], K[1, 2])
            meta_files.append(("intrinsic/intrinsic_depth.txt", read_bytes(intr_file)))
        elif override is None:
            raise RecordingError(
                "ScanNet export has no intrinsic/intrinsic_depth.txt (or give the reader option "
                "'intrinsics')",
                intr_file,
            )
        else:
            default_cam = override
        stems = _numbered(folder / "pose", ".txt")
        if not stems:
            raise RecordingError("no pose/N.txt files", folder / "pose")
        width, height = first_size((folder / "depth" / f"{s}.png" for s in stems), folder)
        intr = make_intrinsics(width, height, default_cam, override)

        color = folder / "color"
        sources = [
            FrameSource(
                key=stem,
                rgb_path=first_existing(color / f"{stem}.jpg", color / f"{stem}.png"),
                depth_path=folder / "depth" / f"{stem}.png",
                pose=partial(read_matrix_pose, folder / "pose" / f"{stem}.txt"),
            )
            for stem in stems
        ]
        pose_files = [(f"pose/{s}.txt", read_bytes(folder / "pose" / f"{s}.txt")) for s in stems]
        return Recording(
            path=str(folder),
            format="scannet",
            identity=identity(meta_files + pose_files),
            intrinsics=intr,
            frames=frame_refs(sources, ImageFormat(intr, depth_scale, resize_rgb=True)),
            up=up_option(opts, self.name),
            meta={"reader": self.name, "depth_scale": depth_scale},
        )

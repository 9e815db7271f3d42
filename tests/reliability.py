"""Helpers of the reliability tests: a tiny simulated house, one-line error checks, small mounts."""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from PIL import Image

from ltc_cli.cli import cli
from ltc_cli.recordings import rle
from ltc_cli.tools.simulate import simulate


def sha256(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def error_line(r) -> str:
    """The one line an ltc error prints: exit 1, one non-empty stderr line, no traceback."""
    assert r.exit_code == 1, (r.exit_code, r.output, r.exception)
    assert isinstance(r.exception, SystemExit), r.exception  # a clean exit, not an exception
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, r.stderr
    assert "Traceback" not in r.output
    return lines[0]


def temp_files(folder) -> list:
    return sorted(Path(folder).glob(".*.tmp-*"))


def tiny_house(root) -> Path:
    """Two laps of the tiny simulated house at 160 x 120 (12 frames each): a second session in a
    second of work."""
    simulate(root, scene="tiny", laps=2, seed=1, width=160, height=120)
    return Path(root)


def many_instances(root, n, w=320, h=240, side=5, wall=4.0) -> Path:
    """One frame of a wall 4 m ahead and n square instances of side x side pixels tiling the image
    (25 points each, boxes of 6.4 cm): a detections file of absurd size but tiny masks."""
    root = Path(root)
    for sub in ("rgb", "depth", "detections"):
        (root / sub).mkdir(parents=True, exist_ok=True)
    meta = {"format": "ltc-recording/1",
            "camera": {"width": w, "height": h, "fx": 250.0, "fy": 250.0, "cx": (w - 1) / 2, "cy": (h - 1) / 2},
            "depth": {"scale": 1000.0, "min": 0.3, "max": 6.0}, "classes": ["box"]}
    (root / "recording.yaml").write_text(yaml.safe_dump(meta))
    # Camera at 1 m looking along world +x (z up): columns of R are the camera's x, y, z axes.
    (root / "poses.txt").write_text("000000 0 0 1 0.5 -0.5 0.5 -0.5\n")
    Image.fromarray(np.full((h, w), int(wall * 1000), np.uint16)).save(root / "depth" / "000000.png")
    Image.fromarray(np.full((h, w, 3), 128, np.uint8)).save(root / "rgb" / "000000.png")
    cols = w // side
    assert n <= cols * (h // side)
    instances = []
    for i in range(n):
        r, c = divmod(i, cols)
        mask = np.zeros((h, w), bool)
        mask[r * side:(r + 1) * side, c * side:(c + 1) * side] = True
        # Scores fall with i, so "the most confident" are the first ones.
        instances.append({"class": "box", "score": round(0.95 - 0.5 * i / n, 6), "mask": rle.encode(mask)})
    (root / "detections" / "000000.json").write_text(json.dumps({"frame": "000000", "instances": instances}))
    return root


def can_mount() -> bool:
    return os.geteuid() == 0 and shutil.which("mount") is not None


@contextlib.contextmanager
def tmpfs(path: Path, size_kb: int):
    """A small tmpfs at ``path`` (root only; the test is skipped where mounting is not allowed)."""
    if not can_mount():
        pytest.skip("mounting a small tmpfs needs root")
    path.mkdir(parents=True, exist_ok=True)
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size_kb}k,mode=0777", "tmpfs", str(path)],
                       capture_output=True, text=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here ({r.stderr.strip()})")
    try:
        yield path
    finally:
        subprocess.run(["umount", "-l", str(path)], capture_output=True)


def remount_read_only(path: Path) -> None:
    r = subprocess.run(["mount", "-o", "remount,ro", str(path)], capture_output=True, text=True)
    if r.returncode != 0:
        pytest.skip(f"cannot remount read-only ({r.stderr.strip()})")


def fill_to(folder: Path, free_bytes: int) -> None:
    """Write a ballast file so that ``free_bytes`` (whole pages) stay free on folder's filesystem."""
    st = os.statvfs(folder)
    free = st.f_bavail * st.f_frsize
    ballast = free - free_bytes
    assert ballast >= 0, (free, free_bytes)
    with open(folder / "ballast", "wb") as fh:
        fh.write(b"\0" * ballast)
        fh.flush()
        os.fsync(fh.fileno())
    st = os.statvfs(folder)
    assert st.f_bavail * st.f_frsize == free_bytes

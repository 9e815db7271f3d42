"""Plain data passed between readers, detectors and the mapping stages (numpy arrays, no I/O)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Callable, Iterator

if TYPE_CHECKING:  # numpy only in annotations here: `ltc --help` imports this module
    import numpy as np


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole camera, no distortion; pixel (u, v) = (fx X/Z + cx, fy Y/Z + cy) in the OpenCV frame."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    @property
    def K(self) -> np.ndarray:
        import numpy as np

        return np.array([[self.fx, 0, self.cx], [0, self.fy, self.cy], [0, 0, 1.0]])


@dataclass
class Frame:
    """One RGB-D frame, already checked by its reader.

    depth_m: (H, W) float32 metres, 0 where there is no reading.
    T_world_camera: (4, 4) camera-to-world pose in the recording's world frame.
    rgb: (H, W, 3) uint8, or None when a detector does not need it. A reader may instead give
        ``rgb_loader``: the colour image is then decoded on the first read of ``frame.rgb`` (a
        detector that never looks at colour, like ``recorded``, never pays for decoding it).
    warnings: problems found while loading or detecting that leave the frame usable (ingest reports
        each one, or stops on it with ``--strict``).
    """

    key: str
    index: int
    depth_m: np.ndarray
    T_world_camera: np.ndarray
    intrinsics: Intrinsics
    rgb: np.ndarray | None = None
    rgb_path: str | None = None
    depth_path: str | None = None
    extra: dict = field(default_factory=dict)
    warnings: list[FrameWarning] = field(default_factory=list)
    rgb_loader: Callable[[], np.ndarray] | None = field(default=None, repr=False, compare=False)


def _frame_rgb(frame: Frame):
    if frame._rgb is None and frame.rgb_loader is not None:
        # Decoded once, then kept (and the loader dropped): FrameError propagates to whoever asked,
        # which in an ingest is the detector, so a bad colour image still skips the frame.
        frame._rgb = frame.rgb_loader()
        frame.rgb_loader = None
    return frame._rgb


def _set_frame_rgb(frame: Frame, value) -> None:
    frame._rgb = value


# ``rgb`` stays a dataclass field (Frame(rgb=...) and its default work as before); the property
# installed after the class is built makes its first read decode the image from ``rgb_loader``.
Frame.rgb = property(_frame_rgb, _set_frame_rgb)


@dataclass(frozen=True)
class FrameWarning:
    """A problem in a recording's file that does not make the frame unusable.

    once: when set, ingest reports only the first warning with this key in each recording (e.g.
        ``"class:lamp"``, so an unknown class is named once, not in every frame).
    """

    message: str
    path: str | None = None
    once: str | None = None

    def __str__(self) -> str:
        return f"{self.path}: {self.message}" if self.path else self.message


@dataclass
class Detection:
    """One instance from a detector.

    mask: (H, W) bool instance mask in the frame's image.
    scores: (K,) class probabilities aligned with the detector's ``classes``; they may sum to less
        than 1 (the rest is "none of these").
    """

    mask: np.ndarray
    scores: np.ndarray


@dataclass
class FrameRef:
    """A frame that is not loaded yet: ``load()`` reads and validates it (raises FrameError).

    ``pose``, when a reader knows the poses without reading the images: ``pose()`` returns what
    ``load().T_world_camera`` would (4, 4), or raises FrameError. The ingest then judges a still
    camera's frames (ingest/keyframes.py) before loading them, and never loads or detects them;
    None: judged once loaded.
    """

    key: str
    index: int
    load: Callable[[], Frame]
    pose: Callable[[], np.ndarray] | None = None


@dataclass
class Recording:
    """An opened recording: what a reader returns.

    identity: a content hash of the recording's metadata and poses, so that the same recording
        moved to another folder keeps its frame keys (re-ingesting is a no-op).
    up: how to make the world z-up: None (already z-up), a 3-vector (the world's up direction), or
        "estimate".
    classes: the recording's class list, when it gives one.
    """

    path: str
    format: str
    identity: str
    intrinsics: Intrinsics
    frames: list[FrameRef]
    up: object = None
    classes: list[str] | None = None
    depth_range: tuple[float, float] | None = None
    meta: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.frames)

    def __iter__(self) -> Iterator[FrameRef]:
        return iter(self.frames)

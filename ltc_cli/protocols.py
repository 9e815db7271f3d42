"""The plugin interfaces: what a detector, an association metric, a maintenance policy and a
recording reader must provide, as ``typing.Protocol`` classes that the hook specs name.

These are structural types: a plugin does not inherit from them, it only has the methods. Checking
with a type checker (``mypy``, ``pyright``) or at run time with ``isinstance`` (they are
``runtime_checkable``; that checks the names, not the signatures) is up to the plugin's author.
The factories are what a plugin registers under a name (``register(name, factory)``, see
:mod:`ltc_cli.hookspecs`); ltc calls them once per ingest (metric, policy) or once per recording
(detector). Readers are registered as objects (or classes) with ``sniff`` and ``open``.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Callable, Protocol, runtime_checkable

from ltc_cli.types import Detection, Frame, Recording

if TYPE_CHECKING:  # only for annotations: keeps this module (imported by `ltc --help`) free of numpy and geometry
    import numpy as np

    from ltc_cli.geometry.boxes import Boxes


@runtime_checkable
class Detector(Protocol):
    """Finds object instances in one frame.

    ``classes`` is the detector's vocabulary; every :class:`~ltc_cli.types.Detection` it returns has
    a boolean mask of the frame's size and a score vector aligned with ``classes``. ``detect`` raises
    :class:`~ltc_cli.errors.FrameError` for a frame it cannot read (the frame is skipped and
    counted) and another :class:`~ltc_cli.errors.LtcError` for a fatal problem. It may append
    :class:`~ltc_cli.types.FrameWarning` objects to ``frame.warnings`` for problems that do not make
    the frame unusable (ingest reports them, and stops on them with ``--strict``).

    A detector whose ``detect`` keeps no state between calls may set the class attribute
    ``thread_safe = True``; ``ingest --jobs N`` then calls it from several threads at once. One that
    never reads ``frame.rgb`` may set ``needs_rgb = False``: the colour image is then not decoded.
    """

    classes: list[str]

    def detect(self, frame: Frame) -> list[Detection]: ...


class DetectorFactory(Protocol):
    """``factory(recording, options) -> Detector``: called once per recording; ``options`` is the
    config's ``detector.options`` mapping (the plugin validates it)."""

    def __call__(self, recording: Recording, options: dict) -> Detector: ...


@runtime_checkable
class Metric(Protocol):
    """Data-association distance (stage 2).

    ``distance(det, cands)`` takes one detection box and M candidate map boxes (each a
    :class:`~ltc_cli.geometry.boxes.Boxes`: corners, visible flags, centres, sizes) and returns their
    distances (M,) float in metres. Smaller is closer; the config's association thresholds apply.

    Optional ``center_bound = True``: the distance is never less than the boxes' centre distance
    less both half diagonals (true of eq. 2 and of the centre distance); the mapper then compares a
    detection only with the map objects that bound lets match (the same decisions, less time).

    Optional ``paired = True``: ``distance(a, b)`` also takes M boxes in ``a`` and returns the
    distance of each pair (a[k], b[k]); the de-duplication after a frame then measures all its
    pairs in one call instead of one call per map object.
    """

    def distance(self, det: Boxes, cands: Boxes) -> np.ndarray: ...


#: ``factory(options) -> Metric``; ``options`` is the config's ``association`` section.
MetricFactory = Callable[[dict], Metric]


@runtime_checkable
class Policy(Protocol):
    """Map maintenance (stage 4): which unmatched objects in view get a non-detection (eq. 4).

    ``non_detections(matched, visible_px, required_px)`` receives, for the M map objects in view of
    a frame, ``matched`` (M,) bool (matched by a detection of this frame), ``visible_px`` (M,) float
    (pixels of the object the camera should have seen: not hidden by other map objects nor by
    nearer observed depth) and ``required_px`` (M,) float (the pixels a non-detection needs), and
    returns (M,) bool: which of them get a non-detection.
    """

    def non_detections(
        self, matched: np.ndarray, visible_px: np.ndarray, required_px: np.ndarray
    ) -> np.ndarray: ...

    # Optional: ``removals(scores (M, C+1)) -> (M,) bool`` decides which objects that just got a
    # non-detection are removed, given their fused class vectors (other last). A policy without it
    # keeps the paper's rule, removal once `other` leads (``static`` never removes). Optional
    # ``removes = False``: the policy removes nothing, not even by the end-of-session absence rule.


#: ``factory(options) -> Policy``; ``options`` is the config's ``maintenance`` section.
PolicyFactory = Callable[[dict], Policy]


@runtime_checkable
class Reader(Protocol):
    """Opens recordings of one layout.

    ``sniff(path)`` says cheaply, without raising, whether a folder is in this layout (used to choose
    a reader when the user names none). ``open(path, options)`` parses the index and pose files and
    returns a :class:`~ltc_cli.types.Recording` whose frames load lazily; it raises
    :class:`~ltc_cli.errors.RecordingError` naming the file at fault when it cannot, and
    :class:`~ltc_cli.errors.ConfigError` for bad ``options`` (the ``--format`` reader's options).
    """

    def sniff(self, path: Path) -> bool: ...

    def open(self, path: Path, options: dict) -> Recording: ...


# What each hook's ``register`` argument is: ``register(name, implementation)``.
RegisterDetector = Callable[[str, DetectorFactory], None]
RegisterMetric = Callable[[str, MetricFactory], None]
RegisterPolicy = Callable[[str, PolicyFactory], None]
RegisterReader = Callable[[str, Reader], None]

__all__ = [
    "Detector", "DetectorFactory", "Metric", "MetricFactory", "Policy", "PolicyFactory", "Reader",
    "RegisterDetector", "RegisterMetric", "RegisterPolicy", "RegisterReader",
]  # fmt: skip

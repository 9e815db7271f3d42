"""The hook specifications of ltc (pluggy project name ``ltc``, entry-point group ``ltc``).

Every hook receives a ``register`` callable and registers implementations *by name*; built-in
plugins under ``plugins/`` use exactly these hooks through the same entry-point group as third-party
packages. A plugin module implements any subset of them with ``@ltc_cli.hookimpl``. The interfaces
the registered objects must have are the ``typing.Protocol`` classes of :mod:`ltc_cli.protocols`.
"""

from __future__ import annotations

import pluggy

from ltc_cli.protocols import RegisterDetector, RegisterMetric, RegisterPolicy, RegisterReader

hookspec = pluggy.HookspecMarker("ltc")
hookimpl = pluggy.HookimplMarker("ltc")


@hookspec
def register_detectors(register: RegisterDetector) -> None:
    """Register detectors: ``register(name, factory)``.

    ``factory`` is a :class:`~ltc_cli.protocols.DetectorFactory`: ``factory(recording, options:
    dict) -> Detector``, called once per recording. A :class:`~ltc_cli.protocols.Detector` has
    ``classes: list[str]`` (its vocabulary) and ``detect(frame) -> list[Detection]`` where a
    :class:`ltc_cli.types.Detection` holds a boolean instance mask of the frame's size and a score
    vector aligned with ``classes``. Detectors may raise :class:`ltc_cli.errors.FrameError` for a
    frame they cannot read (the frame is skipped) and ``LtcError`` for fatal problems.
    """


@hookspec
def register_metrics(register: RegisterMetric) -> None:
    """Register data-association metrics: ``register(name, factory)``.

    ``factory`` is a :data:`~ltc_cli.protocols.MetricFactory`: ``factory(options: dict) -> Metric``
    (options: the ``association`` config section). :meth:`Metric.distance(det, cands)
    <ltc_cli.protocols.Metric.distance>` gives the distance (M,) in metres between one detection box
    and M candidate map boxes, each a :class:`ltc_cli.geometry.boxes.Boxes` (corners, visible flags,
    centres, sizes). Smaller is closer; the association thresholds of the config apply to it.
    Optional attributes let ltc skip pairs that cannot match (``center_bound``) and measure a
    frame's pairs of map objects in one call (``paired``); see the protocol.
    """


@hookspec
def register_policies(register: RegisterPolicy) -> None:
    """Register map-maintenance policies: ``register(name, factory)``.

    ``factory`` is a :data:`~ltc_cli.protocols.PolicyFactory`: ``factory(options: dict) -> Policy``
    (options: the ``maintenance`` config section). :meth:`Policy.non_detections(matched (M,) bool,
    visible_px (M,) float, required_px (M,) float) -> (M,) bool
    <ltc_cli.protocols.Policy.non_detections>` receives, for the M map objects in view of a frame,
    whether each was matched by a detection and how many of its pixels the camera should have seen
    (not hidden by other map objects nor by nearer observed depth), and returns which of them get a
    non-detection (eq. 4). An optional ``Policy.removals(scores (M, C+1)) -> (M,) bool`` decides
    which of those are removed (default: the paper's rule, once `other` leads).
    """


@hookspec
def register_readers(register: RegisterReader) -> None:
    """Register recording readers: ``register(name, reader)``.

    ``reader`` is a :class:`~ltc_cli.protocols.Reader`: ``reader.sniff(path) -> bool`` says whether
    a folder is in its layout (used to choose a reader automatically); ``reader.open(path, options:
    dict) -> Recording`` opens it, raising :class:`ltc_cli.errors.RecordingError` with the file at
    fault when it cannot. A reader that knows the poses without reading the images gives each
    :class:`~ltc_cli.types.FrameRef` a ``pose`` callable: a still camera's frames are then judged
    before loading and never read, detected, or sent to a Dask cluster.
    """

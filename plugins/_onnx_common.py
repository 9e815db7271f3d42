"""What the ONNX detector plugins share: option checking and the onnxruntime session."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from ltc_cli.errors import FrameError, PluginError
from ltc_cli.recordings.images import load_rgb
from ltc_cli.types import Frame


def frame_rgb(frame: Frame, name: str) -> np.ndarray:
    """The frame's colour image (H, W, 3), loaded when the reader left it on disk; it must have the
    depth image's size, since the masks are applied to the depth."""
    rgb = frame.rgb
    if rgb is None:
        if not frame.rgb_path:
            raise FrameError(f"{name} needs the colour image; frame {frame.key} has none")
        rgb = load_rgb(frame.rgb_path)
    if frame.depth_m is not None and tuple(frame.depth_m.shape[:2]) != tuple(rgb.shape[:2]):
        raise FrameError(
            f"colour image is {rgb.shape[1]}x{rgb.shape[0]} but depth is "
            f"{frame.depth_m.shape[1]}x{frame.depth_m.shape[0]}",
            frame.rgb_path or frame.key,
        )
    return rgb


class Options:
    """Checks a detector's options; every error names the detector (and the file, if any)."""

    def __init__(self, name: str):
        self.name = name

    def fail(self, message: str, path=None):
        raise PluginError(f"{self.name}: {message}", path=path)

    def merged(self, defaults: dict, given: dict | None) -> dict:
        """The defaults updated with the given options; an unknown option is an error (a typo
        would otherwise be ignored silently)."""
        given = dict(given or {})
        unknown = sorted(set(given) - set(defaults))
        if unknown:
            self.fail(f"unknown option(s) {', '.join(map(repr, unknown))} (known: {', '.join(defaults)})")
        return {**defaults, **given}

    def number(self, opts: dict, key: str, lo: float, hi: float, lo_open=False, hi_open=False) -> float:
        v = opts[key]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            self.fail(f"option {key!r} must be a number, got {v!r}")
        if (v <= lo if lo_open else v < lo) or (v >= hi if hi_open else v > hi):
            lo_b, hi_b = "(" if lo_open else "[", ")" if hi_open else "]"
            self.fail(f"option {key!r} must be in {lo_b}{lo}, {hi}{hi_b}, got {v!r}")
        return float(v)

    def integer(self, opts: dict, key: str, lo: int) -> int:
        v = opts[key]
        if isinstance(v, bool) or not isinstance(v, int) or v < lo:
            self.fail(f"option {key!r} must be an integer >= {lo}, got {v!r}")
        return int(v)

    def names(self, value, key: str) -> list[str]:
        if not isinstance(value, (list, tuple)) or not value or not all(isinstance(n, str) and n for n in value):
            self.fail(f"option {key!r} must be a non-empty list of class names, got {value!r}")
        if len(set(value)) != len(value):
            self.fail(f"option {key!r} lists a class twice")
        return list(value)

    def model_path(self, opts: dict) -> Path:
        model = opts.get("model")
        if not model or not isinstance(model, (str, os.PathLike)):
            self.fail("option 'model' is required: the path to an ONNX file (no model is downloaded)")
        path = Path(os.path.expanduser(str(model)))
        if not path.is_file():
            self.fail("model file not found", path=path)
        return path

    def session(self, path: Path, threads: int):
        """An onnxruntime CPU session with ``threads`` intra-op threads, run sequentially."""
        try:
            import onnxruntime as ort
        except ImportError:  # pragma: no cover - onnxruntime is a dependency
            self.fail("needs the onnxruntime package (pip install onnxruntime)")
        so = ort.SessionOptions()
        so.intra_op_num_threads = threads
        so.inter_op_num_threads = 1
        so.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
        so.log_severity_level = 3  # onnxruntime's own warnings would bypass ltc's error reporting
        try:
            return ort.InferenceSession(str(path), sess_options=so, providers=["CPUExecutionProvider"])
        except Exception as exc:  # onnxruntime raises its own exception types for bad files
            self.fail(f"cannot load ONNX model ({exc.__class__.__name__}: {str(exc).splitlines()[0]})", path)

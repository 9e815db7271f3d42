"""What the ONNX detector plugins share: their options (JSON Schema), the model file and the
onnxruntime session (:class:`OnnxDetector`), the frame's colour image, and bilinear sampling of
mask grids."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import NoReturn

import numpy as np

from ltc_cli.errors import FrameError, PluginError
from ltc_cli.recordings.images import load_rgb
from ltc_cli.threads import threads_per_job
from ltc_cli.types import Frame
from ltc_cli.validation import check_options

NAMES = {"type": "array", "items": {"type": "string", "minLength": 1}, "minItems": 1, "uniqueItems": True}
# Options both detectors take; each adds its own (and its score_threshold default) in options_schema.
COMMON_OPTIONS = {
    "model": {"type": "string", "minLength": 1,
              "description": "the path to an ONNX file (no model is downloaded)"},
    "score_threshold": {"type": "number", "minimum": 0, "maximum": 1},
    "mask_threshold": {"type": "number", "exclusiveMinimum": 0, "exclusiveMaximum": 1, "default": 0.5},
    "classes": {"anyOf": [{"type": "null"}, NAMES], "default": None,
                "description": "null or a non-empty list of distinct class names (keep only these)"},
    "class_names": {"anyOf": [{"type": "null"}, NAMES], "default": None,
                    "description": "null or a non-empty list of distinct class names (overriding the model's)"},
    "max_detections": {"type": "integer", "minimum": 1, "default": 50},
    "provider": {"enum": ["cpu", "openvino", "auto"], "default": "cpu",
                 "description": "onnxruntime execution provider: cpu; openvino (needs ltc[openvino]); "
                                "auto: openvino when installed, else cpu"},
    "precision": {"enum": ["f32", "bf16", "f16"], "default": "f32",
                  "description": "OpenVINO's inference precision hint (provider openvino or auto); "
                                 "bf16 / f16 change the detections a little; the cpu provider runs f32"},
    "threads": {"anyOf": [{"type": "null"}, {"type": "integer", "minimum": 1}], "default": None,
                "description": "onnxruntime intra-op threads; null: the cores divided by ingest --jobs"},
}  # fmt: skip


def options_schema(score_threshold: float, **extra: dict) -> dict:
    """A detector's options schema: the common options, its score threshold default and its own."""
    props = {
        **COMMON_OPTIONS,
        "score_threshold": {**COMMON_OPTIONS["score_threshold"], "default": score_threshold},
        **extra,
    }
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", "type": "object",
            "required": ["model"], "additionalProperties": False, "properties": props}  # fmt: skip


def fail(name: str, message: str, path=None) -> NoReturn:
    """Raise PluginError naming the detector (and the file, if any)."""
    raise PluginError(f"{name}: {message}", path=path)


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


def bilinear_taps(h: int, w: int, ys: np.ndarray, xs: np.ndarray):
    """(y0, y1, wy (R, 1), x0, x1, wx (1, C)): the two rows and columns of a grid (h, w) around each
    row coordinate ys (R,) and column coordinate xs (C,), and the weight of the second of each
    (cell centres at integers; beyond the edges the edge cell)."""
    ys = np.clip(ys, 0.0, h - 1.0)
    xs = np.clip(xs, 0.0, w - 1.0)
    y0 = np.floor(ys).astype(np.int64)
    x0 = np.floor(xs).astype(np.int64)
    y1 = np.minimum(y0 + 1, h - 1)
    x1 = np.minimum(x0 + 1, w - 1)
    return y0, y1, (ys - y0)[:, None], x0, x1, (xs - x0)[None, :]


def bilinear_sample(grid: np.ndarray, ys: np.ndarray, xs: np.ndarray) -> np.ndarray:
    """Sample grid (h, w) at the outer product of row coords ys (R,) and column coords xs (C,).

    Coordinates are in grid cells with cell centres at integers (the ``align_corners=False``
    convention); outside the grid the edge value is repeated. Returns (R, C).
    """
    y0, y1, wy, x0, x1, wx = bilinear_taps(*grid.shape, ys, xs)
    if y0.size == 0 or x0.size == 0:
        return np.zeros((y0.size, x0.size))
    # Separable: each grid row that is sampled is interpolated along the columns once, (rows, C),
    # and the output rows pick two of them. The same products and sums, element by element, as
    # interpolating the four corners of every output pixel (so the same bits), for a fraction of
    # the work when the output has many more rows than the grid (a mask upsampled 8x).
    lo, hi = int(y0.min()), int(y1.max()) + 1
    band = grid[lo:hi]
    along = band[:, x0] * (1 - wx) + band[:, x1] * wx
    out = along[y0 - lo]
    out *= 1 - wy
    bottom = along[y1 - lo]
    bottom *= wy
    out += bottom  # top (1 - wy) + bottom wy, in place
    return out


class OnnxDetector:
    """Base of the ONNX detectors: checks the options against ``OPTIONS_SCHEMA``, finds the model
    file and opens the onnxruntime session. Subclasses set ``NAME`` and ``OPTIONS_SCHEMA``."""

    NAME = "onnx"
    OPTIONS_SCHEMA: dict = options_schema(0.5)
    # detect() keeps no state between calls (onnxruntime sessions may be run from several threads),
    # so ingest --jobs may run it on several frames at once.
    thread_safe = True

    def __init__(self, model_path, options: dict | None = None):
        given = {k: v for k, v in (options or {}).items() if k != "model"}
        if model_path is not None:
            given["model"] = os.fspath(model_path) if isinstance(model_path, (str, os.PathLike)) else model_path
        self.options = check_options(given, self.OPTIONS_SCHEMA, self.NAME, PluginError)
        self.model_path = Path(os.path.expanduser(self.options["model"]))
        if not self.model_path.is_file():
            self.fail("model file not found", path=self.model_path)
        self.score_threshold = float(self.options["score_threshold"])
        self.mask_threshold = float(self.options["mask_threshold"])
        self.max_detections = int(self.options["max_detections"])
        threads = self.options["threads"]
        self.threads = int(threads) if threads is not None else threads_per_job()

    @classmethod
    def from_options(cls, recording, options: dict):
        """The registered factory: ``factory(recording, options)``."""
        options = dict(options or {})
        return cls(options.get("model"), options)

    def fail(self, message: str, path=None) -> NoReturn:
        fail(self.NAME, message, path)

    def open_session(self):
        """An onnxruntime session on the ``provider`` asked for, with ``threads`` intra-op threads,
        run sequentially."""
        try:
            import onnxruntime as ort
        except ImportError:  # pragma: no cover - onnxruntime is a dependency
            self.fail("needs the onnxruntime package (pip install onnxruntime)")
        providers = execution_providers(self.options["provider"], ort.get_available_providers(), self.threads,
                                        self.NAME, self.options["precision"])
        so = ort.SessionOptions()
        so.intra_op_num_threads = self.threads
        so.inter_op_num_threads = 1
        so.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
        # Idle intra-op threads would busy-wait for the next operator: on 2 shared cores, 2 threads
        # took 36 ms wall / 36 ms CPU per fp32 frame with spinning, 20 / 20 without (1 thread: 18).
        so.add_session_config_entry("session.intra_op.allow_spinning", "0")
        so.log_severity_level = 3  # onnxruntime's own warnings would bypass ltc's error reporting
        try:
            session = ort.InferenceSession(str(self.model_path), sess_options=so, providers=providers)
        except Exception as exc:  # onnxruntime raises its own exception types for bad files
            self.fail(
                f"cannot load ONNX model ({exc.__class__.__name__}: {str(exc).splitlines()[0]})", self.model_path
            )
        # onnxruntime falls back to its CPU provider, with a warning on stderr only, when a provider
        # it was given cannot be created: asked for, OpenVINO must be there.
        if providers[0] != CPU[0] and OPENVINO not in session.get_providers():
            self.fail("onnxruntime could not start its OpenVINO provider for this model", self.model_path)
        return session


OPENVINO = "OpenVINOExecutionProvider"


CPU = ["CPUExecutionProvider"]


def execution_providers(choice: str, available: list[str], threads: int, name: str, precision: str = "f32") -> list:
    """onnxruntime's ``providers`` list for the ``provider`` option (CPU always last, for the
    operators another provider does not take); PluginError when openvino is asked for and missing,
    or when a precision other than f32 is asked of the cpu provider. ``precision`` becomes
    OpenVINO's ``INFERENCE_PRECISION_HINT`` (its CPU plugin takes f32 and bf16; f16 where the CPU
    has it)."""
    if choice == "cpu" and precision != "f32":
        fail(name, f"precision {precision} needs provider openvino (or auto); the cpu provider runs f32")
    if choice == "cpu" or (choice == "auto" and OPENVINO not in available):
        return list(CPU)
    if OPENVINO not in available:
        fail(name, "provider openvino needs onnxruntime-openvino (pip uninstall onnxruntime, then pip install "
                   "'ltc[openvino]'); this onnxruntime has " + ", ".join(available))
    options = {"device_type": "CPU", "num_of_threads": str(threads)}
    if precision != "f32":
        options["load_config"] = json.dumps({"CPU": {"INFERENCE_PRECISION_HINT": precision}})
    return [(OPENVINO, options), *CPU]

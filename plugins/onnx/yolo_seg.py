"""Detector ``onnx-yolo-seg``: any Ultralytics YOLOv8 / YOLO11 ``-seg`` ONNX export, on onnxruntime's CPU.

Everything model-specific is read from the model: input size (from the input's shape, or the
``imgsz`` metadata for dynamic exports), class names (``names`` metadata, a Python dict literal
parsed with ``ast.literal_eval``), stride, the number of mask prototypes. The pipeline follows
Ultralytics' own predictor:

1. letterbox the RGB image into the input (scale to fit, centred, pad value 114), RGB / 255;
2. ``output0`` [1, 4 + nc + nm, A]: per anchor cx, cy, w, h (input pixels), nc class scores
   (already sigmoid, no objectness), nm mask coefficients; keep anchors whose best class score
   reaches ``score_threshold``, then class-aware NMS;
3. ``output1`` [1, nm, mh, mw] prototypes: mask = sigmoid(coefs @ protos), cropped to the box and
   brought back through the letterbox to the original image, thresholded at ``mask_threshold``.

Options (config ``detector.options``): ``model`` (path, required), ``score_threshold`` (0.25),
``nms_iou`` (0.45), ``mask_threshold`` (0.5), ``classes`` (keep only these names; default all),
``class_names`` (override the model's names), ``max_detections`` (50), ``threads`` (null: the cores
divided by ``--jobs``), ``provider`` (cpu, openvino, auto), ``precision`` (f32; bf16 / f16 for
OpenVINO), ``imgsz`` (input size for exports with dynamic height / width; default the model's
``imgsz`` or 640).
"""

from __future__ import annotations

import ast
import math
from functools import partial

import numpy as np

from ltc_cli import hookimpl
from ltc_cli.errors import PluginError
from ltc_cli.types import Detection, Frame
from ltc_plugins.onnx.common import OnnxDetector, bilinear_sample, fail, frame_rgb, options_schema
from ltc_plugins.onnx.resize import resize_bilinear

NAME = "onnx-yolo-seg"
OPTIONS_SCHEMA = options_schema(
    0.25,
    nms_iou={"type": "number", "exclusiveMinimum": 0, "maximum": 1, "default": 0.45},
    imgsz={"description": "null, n or [height, width] (input size of exports with a dynamic size)",
           "anyOf": [{"type": "null"}, {"type": "integer", "minimum": 1},
                     {"type": "array", "items": {"type": "integer", "minimum": 1}, "minItems": 2, "maxItems": 2}],
           "default": None},
)  # fmt: skip
PAD_VALUE = 114  # Ultralytics' letterbox grey
# Candidates entering NMS: bounds the O(n^2) NMS when a low threshold lets thousands through.
MAX_NMS_CANDIDATES = 3000
_fail = partial(fail, NAME)


# --------------------------------------------------------------------------------------------------
# Numeric helpers


def sigmoid(x: np.ndarray) -> np.ndarray:
    # exp of a negated clipped value: no overflow warnings for large logits.
    return 1.0 / (1.0 + np.exp(-np.clip(x, -60.0, 60.0)))


def nms(boxes_xyxy: np.ndarray, scores: np.ndarray, iou_threshold: float) -> np.ndarray:
    """Greedy non-maximum suppression: indices (M,) of the kept boxes, best score first.

    boxes_xyxy (N, 4), scores (N,). A box is dropped when its IoU with a kept, higher-scoring box
    exceeds ``iou_threshold``. Class-aware NMS is this on boxes offset per class.
    """
    order = np.argsort(-scores, kind="stable")
    x1, y1, x2, y2 = boxes_xyxy.T
    area = np.maximum(x2 - x1, 0) * np.maximum(y2 - y1, 0)
    keep = []
    while order.size:
        i = order[0]
        keep.append(i)
        rest = order[1:]
        w = np.maximum(0.0, np.minimum(x2[i], x2[rest]) - np.maximum(x1[i], x1[rest]))
        h = np.maximum(0.0, np.minimum(y2[i], y2[rest]) - np.maximum(y1[i], y1[rest]))
        inter = w * h
        iou = inter / np.maximum(area[i] + area[rest] - inter, 1e-12)
        order = rest[iou <= iou_threshold]
    return np.array(keep, dtype=np.int64)


def parse_names(text: str, path=None) -> list[str]:
    """Class names from Ultralytics' ``names`` metadata: "{0: 'person', 1: 'bicycle'}" (or a list).

    ``ast.literal_eval`` only accepts literals, so a crafted model cannot run code here.
    """
    try:
        value = ast.literal_eval(text)
    except (ValueError, SyntaxError, TypeError, MemoryError, RecursionError):
        _fail("model metadata 'names' is not a dict or list literal", path)
    if isinstance(value, dict):
        if sorted(value) != list(range(len(value))) or not all(isinstance(v, str) for v in value.values()):
            _fail("model metadata 'names' must map 0..n-1 to class names", path)
        return [value[i] for i in range(len(value))]
    if isinstance(value, (list, tuple)) and all(isinstance(v, str) for v in value):
        return list(value)
    _fail("model metadata 'names' must be a dict or list of class names", path)


def _size_pair(value, what: str, path=None) -> tuple[int, int]:
    """(height, width) from an int or a [h, w] list, as in Ultralytics' ``imgsz``."""
    if isinstance(value, str):
        try:
            value = ast.literal_eval(value)
        except (ValueError, SyntaxError):
            _fail(f"{what} {value!r} is not a size", path)
    if isinstance(value, int) and not isinstance(value, bool):
        value = [value, value]
    if (
        not isinstance(value, (list, tuple))
        or len(value) != 2
        or not all(isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in value)
    ):
        _fail(f"{what} must be an integer or [height, width], got {value!r}", path)
    return int(value[0]), int(value[1])


# --------------------------------------------------------------------------------------------------
# The detector


class YoloSegDetector(OnnxDetector):
    """Ultralytics YOLOv8 / YOLO11 instance segmentation through onnxruntime (CPU).

    classes: the detector's vocabulary (the model's names, or the ``classes`` option's subset);
        every Detection's ``scores`` (K,) is aligned with it.
    """

    NAME = NAME
    OPTIONS_SCHEMA = OPTIONS_SCHEMA

    def __init__(self, model_path, options: dict | None = None):
        super().__init__(model_path, options)
        self.nms_iou = float(self.options["nms_iou"])
        self.session = self.open_session()
        self._read_signature(self.options)

    # -- model introspection ------------------------------------------------------------------------

    def _read_signature(self, opts: dict) -> None:
        path = self.model_path
        meta = self.session.get_modelmeta().custom_metadata_map or {}
        task = meta.get("task")
        if task is not None and task != "segment":
            _fail(f"model is a {task!r} model; this detector needs a '-seg' (segment) export", path)
        if str(meta.get("end2end", "False")).lower() == "true":
            _fail("model was exported with NMS inside (end2end); export it with nms=False", path)

        inputs = self.session.get_inputs()
        if len(inputs) != 1:
            _fail(f"model must have one input (images), has {len(inputs)}", path)
        inp = inputs[0]
        self.input_name = inp.name
        self.input_dtype = np.float16 if "float16" in inp.type else np.float32
        shape = list(inp.shape)
        if len(shape) != 4 or (isinstance(shape[1], int) and shape[1] != 3):
            _fail(f"model input must be [batch, 3, height, width], is {shape}", path)
        self.batch = shape[0] if isinstance(shape[0], int) and shape[0] > 0 else 1
        try:
            self.stride = int(meta.get("stride", 32))
        except ValueError:
            self.stride = 32
        if isinstance(shape[2], int) and isinstance(shape[3], int) and shape[2] > 0 and shape[3] > 0:
            self.input_hw = (shape[2], shape[3])
        else:
            # Dynamic height / width: the option, the export's imgsz, or Ultralytics' default 640,
            # rounded up to the stride (the network downsamples by it).
            if opts.get("imgsz") is not None:
                hw = _size_pair(opts["imgsz"], "option 'imgsz'")
            elif "imgsz" in meta:
                hw = _size_pair(meta["imgsz"], "model metadata 'imgsz'", path)
            else:
                hw = (640, 640)
            s = max(self.stride, 1)
            self.input_hw = tuple(int(math.ceil(v / s) * s) for v in hw)

        outputs = self.session.get_outputs()
        by_name = {o.name: o for o in outputs}
        if "output0" in by_name and "output1" in by_name:
            self._out_names = ("output0", "output1")
        elif len(outputs) == 2:
            # Some converters rename outputs: the detections are rank 3, the prototypes rank 4.
            ranked = sorted(outputs, key=lambda o: len(o.shape))
            if [len(o.shape) for o in ranked] != [3, 4]:
                _fail("model outputs must be detections [1, C, A] and prototypes [1, nm, h, w]", path)
            self._out_names = (ranked[0].name, ranked[1].name)
        else:
            _fail(
                f"model has {len(outputs)} output(s); a '-seg' export has output0 (detections) and "
                "output1 (mask prototypes)",
                path,
            )

        det_shape = by_name[self._out_names[0]].shape
        proto_shape = by_name[self._out_names[1]].shape
        nm = proto_shape[1] if isinstance(proto_shape[1], int) else None
        channels = det_shape[1] if isinstance(det_shape[1], int) else None
        nc = channels - 4 - nm if (nm is not None and channels is not None) else None

        if opts.get("class_names") is not None:
            names = list(opts["class_names"])
        elif "names" in meta:
            names = parse_names(meta["names"], path)
        elif nc is not None and nc > 0:
            names = [f"class_{i}" for i in range(nc)]
        else:
            _fail("model has no 'names' metadata and a dynamic output shape; give 'class_names'", path)
        if nc is not None and nc != len(names):
            _fail(f"model predicts {nc} classes but names {len(names)}", path)
        self.model_names = names

        if opts.get("classes") is not None:
            wanted = list(opts["classes"])
            missing = [c for c in wanted if c not in names]
            if missing:
                _fail(
                    f"option 'classes' names {', '.join(map(repr, missing))}, not in the model's "
                    f"classes ({', '.join(names[:10])}{', ...' if len(names) > 10 else ''})",
                    path,
                )
            self.class_idx = np.array([names.index(c) for c in wanted], dtype=np.int64)
        else:
            self.class_idx = np.arange(len(names), dtype=np.int64)
        self.classes = [names[i] for i in self.class_idx]

    # -- inference ----------------------------------------------------------------------------------

    def letterbox(self, rgb: np.ndarray) -> tuple[np.ndarray, float, tuple[int, int]]:
        """Image (H, W, 3) uint8 -> (input (1|B, 3, ih, iw), scale r, (pad_left, pad_top)).

        Same rounding as Ultralytics' LetterBox: the image is scaled by r = min(ih / H, iw / W),
        centred, and the odd padding pixel goes to the bottom / right.
        """
        h0, w0 = rgb.shape[:2]
        ih, iw = self.input_hw
        r = min(ih / h0, iw / w0)
        nw, nh = int(round(w0 * r)), int(round(h0 * r))
        left = int(round((iw - nw) / 2 - 0.1))
        top = int(round((ih - nh) / 2 - 0.1))
        img = resize_bilinear(rgb, nw, nh)  # Pillow's BILINEAR, bit for bit (resize.py)
        # The input straight from the image (uint8 -> float, / 255 in the input's type: the values of
        # a padded canvas's astype / 255 without building it), the padding as one constant.
        one = np.empty((3, ih, iw), dtype=self.input_dtype)
        one[:, :top] = one[:, top + nh :] = one[:, :, :left] = one[:, :, left + nw :] = (
            self.input_dtype(PAD_VALUE) / self.input_dtype(255.0)
        )
        np.divide(img.transpose(2, 0, 1), self.input_dtype(255.0), out=one[:, top : top + nh, left : left + nw])
        x = one[None]
        if self.batch > 1:  # a fixed-batch export: fill the batch, read the first result
            x = np.repeat(x, self.batch, axis=0)
        return x, r, (left, top)

    def predict(self, rgb: np.ndarray):
        """Run the model on one RGB image (H, W, 3) uint8.

        Returns ``boxes (N, 4)`` x1 y1 x2 y2 in image pixels, ``labels (N,)`` index into
        ``classes``, ``scores (N, K)`` per-class scores aligned with ``classes`` (raw sigmoid
        scores), ``masks (N, H, W)`` bool; best first, at most ``max_detections``.
        """
        h0, w0 = rgb.shape[:2]
        x, r, (left, top) = self.letterbox(rgb)
        out0, out1 = self.session.run(list(self._out_names), {self.input_name: x})
        out0 = np.asarray(out0[0], dtype=np.float32)
        protos = np.asarray(out1[0], dtype=np.float32)  # (nm, mh, mw)
        nm, mh, mw = protos.shape
        n_all = len(self.model_names)
        if out0.shape[0] != 4 + n_all + nm:
            if out0.shape[1] == 4 + n_all + nm:  # [A, C] layout from some converters
                out0 = out0.T
            else:
                raise PluginError(
                    f"{NAME}: output0 has {out0.shape[0]} channels, expected 4 + {n_all} classes + "
                    f"{nm} mask coefficients",
                    path=self.model_path,
                )
        preds = out0.T  # (A, 4 + nc + nm)
        # Scores stay in the output's (class, anchor) layout: contiguous rows, no (A, K) copy.
        cls_scores = out0[4 : 4 + n_all]
        if self.class_idx.size != n_all:
            cls_scores = cls_scores[self.class_idx]  # (K, A)
        # The best class is only needed for the anchors that pass: the maximum (a fast reduction
        # down the rows) picks them, the argmax runs on their columns alone. The same values: the
        # maximum is the score at the argmax (and NaN, never a candidate, either way).
        conf = cls_scores.max(axis=0)
        cand = np.flatnonzero(conf >= self.score_threshold)
        empty = (
            np.zeros((0, 4), np.float32), np.zeros(0, np.int64),
            np.zeros((0, len(self.classes)), np.float32), np.zeros((0, h0, w0), bool),
        )  # fmt: skip
        if cand.size == 0:
            return empty
        if cand.size > MAX_NMS_CANDIDATES:
            cand = cand[np.argsort(-conf[cand], kind="stable")[:MAX_NMS_CANDIDATES]]
        best = np.zeros(len(conf), dtype=np.int64)
        best[cand] = cls_scores[:, cand].argmax(axis=0)
        cxcywh = preds[cand, :4].astype(np.float64)
        boxes_in = np.concatenate(
            [cxcywh[:, :2] - cxcywh[:, 2:] / 2, cxcywh[:, :2] + cxcywh[:, 2:] / 2], axis=1
        )
        # Class-aware NMS in one pass: boxes of different classes are moved far apart.
        offset = best[cand, None] * float(max(self.input_hw) * 4 + 1)
        keep = nms(boxes_in + offset, conf[cand], self.nms_iou)[: self.max_detections]
        cand, boxes_in = cand[keep], boxes_in[keep]

        # Undo the letterbox: input pixels -> image pixels.
        boxes = (boxes_in - [left, top, left, top]) / r
        boxes[:, [0, 2]] = boxes[:, [0, 2]].clip(0, w0)
        boxes[:, [1, 3]] = boxes[:, [1, 3]].clip(0, h0)

        coefs = preds[cand, 4 + n_all :]  # (N, nm)
        prob = sigmoid(coefs @ protos.reshape(nm, -1)).reshape(-1, mh, mw)  # (N, mh, mw)
        ih, iw = self.input_hw
        masks = np.zeros((len(cand), h0, w0), dtype=bool)
        nonempty = np.zeros(len(cand), dtype=bool)
        for k, (x1, y1, x2, y2) in enumerate(boxes):
            # The crop to the box is done at image resolution (pixels whose centre is in the box):
            # the same crop as in prototype space, without the 4-pixel staircase at the box edges.
            u0, u1 = int(math.ceil(x1 - 0.5)), int(math.floor(x2 - 0.5))
            v0, v1 = int(math.ceil(y1 - 0.5)), int(math.floor(y2 - 0.5))
            u0, v0 = max(u0, 0), max(v0, 0)
            u1, v1 = min(u1, w0 - 1), min(v1, h0 - 1)
            if u1 < u0 or v1 < v0:
                continue
            # Image pixel centre -> input pixel -> prototype cell (cell centres at integers).
            xs = ((np.arange(u0, u1 + 1) + 0.5) * r + left) * (mw / iw) - 0.5
            ys = ((np.arange(v0, v1 + 1) + 0.5) * r + top) * (mh / ih) - 0.5
            inside = bilinear_sample(prob[k], ys, xs) > self.mask_threshold
            masks[k, v0 : v1 + 1, u0 : u1 + 1] = inside
            nonempty[k] = inside.any()
        scores = cls_scores[:, cand].T.astype(np.float32)
        labels = best[cand]
        if not nonempty.all():  # (a copy of every mask otherwise)
            boxes, labels, scores, masks = boxes[nonempty], labels[nonempty], scores[nonempty], masks[nonempty]
        return boxes.astype(np.float32), labels, scores, masks

    def detect(self, frame: Frame) -> list[Detection]:
        """Instances in a frame: masks at the frame's resolution, scores aligned with ``classes``.

        Scores are the anchor's per-class sigmoid scores; they are independent per class, so when
        they add up to more than 1 they are scaled to sum to 1 (a Detection's scores are
        probabilities, the rest is "none of these").
        """
        rgb = frame_rgb(frame, NAME)
        _, _, scores, masks = self.predict(rgb)
        total = scores.sum(axis=1, keepdims=True)
        scores = np.where(total > 1.0, scores / np.maximum(total, 1e-12), scores)
        return [Detection(mask=m, scores=s) for m, s in zip(masks, scores)]


@hookimpl
def register_detectors(register):
    register(NAME, YoloSegDetector.from_options)

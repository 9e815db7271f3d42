"""Detector ``onnx-maskrcnn``: the ONNX model zoo Mask R-CNN layout (MaskRCNN-10 / -12), onnxruntime CPU.

The zoo model (maskrcnn-benchmark, R-50-FPN) takes one ``image`` float [3, H, W]: BGR, minus the
pixel mean [102.9801, 115.9465, 122.7717], resized so the short side is 800 (long side at most
1333) and zero-padded to multiples of 32. NMS is inside the graph; its outputs are, in this order
(the zoo's file names them by number, not by meaning):

- boxes [N, 4] x1 y1 x2 y2 in the input's pixels,
- labels [N] int64: COCO category indices, 1-based (0 is the background),
- scores [N],
- masks [N, 1, 28, 28]: per-instance foreground probability in the box, pasted into the image
  (bilinear, the box grown by one mask cell of zero padding on each side as in maskrcnn-benchmark)
  and thresholded.

Mask R-CNN gives one score per instance, at its label; the rest of the score vector is unknown and
left at 0 (the map's "other" takes it).

Options: ``model`` (path, required), ``score_threshold`` (0.5), ``mask_threshold`` (0.5),
``classes`` (keep only these names), ``class_names`` (names of labels 1..n; default the 80 COCO
names), ``max_detections`` (50), ``threads`` (1), ``min_size`` (800; 0 = feed the image at its own
size), ``max_size`` (1333).
"""

from __future__ import annotations

import math

import numpy as np
from PIL import Image

from ltc_cli import hookimpl
from ltc_cli.errors import PluginError
from ltc_cli.types import Detection, Frame
from ltc_plugins.onnx.common import OnnxDetector, bilinear_sample, frame_rgb, options_schema

NAME = "onnx-maskrcnn"

# The 80 COCO category names in the zoo's order (coco_classes.txt without its "__background" line):
# label l of the model is COCO_CLASSES[l - 1].
COCO_CLASSES = [
    "person", "bicycle", "car", "motorcycle", "airplane", "bus", "train", "truck", "boat",
    "traffic light", "fire hydrant", "stop sign", "parking meter", "bench", "bird", "cat", "dog",
    "horse", "sheep", "cow", "elephant", "bear", "zebra", "giraffe", "backpack", "umbrella",
    "handbag", "tie", "suitcase", "frisbee", "skis", "snowboard", "sports ball", "kite",
    "baseball bat", "baseball glove", "skateboard", "surfboard", "tennis racket", "bottle",
    "wine glass", "cup", "fork", "knife", "spoon", "bowl", "banana", "apple", "sandwich", "orange",
    "broccoli", "carrot", "hot dog", "pizza", "donut", "cake", "chair", "couch", "potted plant",
    "bed", "dining table", "toilet", "tv", "laptop", "mouse", "remote", "keyboard", "cell phone",
    "microwave", "oven", "toaster", "sink", "refrigerator", "book", "clock", "vase", "scissors",
    "teddy bear", "hair drier", "toothbrush",
]  # fmt: skip
BACKGROUND_NAMES = {"__background", "__background__", "background", "__bg"}

PIXEL_MEAN_BGR = np.array([102.9801, 115.9465, 122.7717], dtype=np.float32)
SIZE_DIVISIBILITY = 32

OPTIONS_SCHEMA = options_schema(
    0.5,
    min_size={"type": "integer", "minimum": 0, "default": 800,
              "description": "short side of the model's input; 0 = the image's own size"},
    max_size={"type": "integer", "minimum": 1, "default": 1333, "description": "long side at most"},
)  # fmt: skip


def paste_mask(mask28: np.ndarray, box_xyxy, height: int, width: int, threshold: float) -> np.ndarray:
    """Paste a box-relative probability mask (m, m) into an image mask (height, width) bool.

    The mask's m x m cells tile the box; it is padded with one cell of zeros on each side (as
    maskrcnn-benchmark's Masker does) so that the foreground fades out at the box edge instead of
    being cut, then sampled bilinearly at the centres of the image pixels it covers.
    """
    m_h, m_w = mask28.shape
    x1, y1, x2, y2 = (float(v) for v in box_xyxy)
    bw, bh = max(x2 - x1, 1e-6), max(y2 - y1, 1e-6)
    padded = np.zeros((m_h + 2, m_w + 2), dtype=np.float32)
    padded[1:-1, 1:-1] = mask28
    cell_w, cell_h = bw / m_w, bh / m_h
    # Pixels whose centres fall in the box grown by one cell: beyond it the padded mask is 0.
    u0 = max(int(math.ceil(x1 - cell_w - 0.5)), 0)
    u1 = min(int(math.floor(x2 + cell_w - 0.5)), width - 1)
    v0 = max(int(math.ceil(y1 - cell_h - 0.5)), 0)
    v1 = min(int(math.floor(y2 + cell_h - 0.5)), height - 1)
    out = np.zeros((height, width), dtype=bool)
    if u1 < u0 or v1 < v0:
        return out
    # Pixel centre -> mask cell coordinate (cell centres at integers), +1 for the padding.
    xs = ((np.arange(u0, u1 + 1) + 0.5) - x1) / cell_w - 0.5 + 1.0
    ys = ((np.arange(v0, v1 + 1) + 0.5) - y1) / cell_h - 0.5 + 1.0
    out[v0 : v1 + 1, u0 : u1 + 1] = bilinear_sample(padded, ys, xs) > threshold
    return out


class MaskRcnnDetector(OnnxDetector):
    """ONNX model zoo Mask R-CNN through onnxruntime (CPU).

    classes: the vocabulary (``class_names`` or COCO's 80, possibly filtered by ``classes``); each
        Detection's ``scores`` (K,) holds the instance's score at its class and 0 elsewhere.
    """

    NAME = NAME
    OPTIONS_SCHEMA = OPTIONS_SCHEMA

    def __init__(self, model_path, options: dict | None = None):
        super().__init__(model_path, options)
        opts = self.options
        self.min_size = int(opts["min_size"])
        self.max_size = int(opts["max_size"])

        names = COCO_CLASSES
        if opts["class_names"] is not None:
            names = list(opts["class_names"])
            if names[0].lower() in BACKGROUND_NAMES:  # an 81-entry list with the background first
                names = names[1:]
        self.label_names = list(names)  # label l -> label_names[l - 1]
        if opts["classes"] is not None:
            wanted = list(opts["classes"])
            missing = [c for c in wanted if c not in names]
            if missing:
                self.fail(f"option 'classes' names {', '.join(map(repr, missing))}, not a class of the model")
            self.classes = wanted
        else:
            self.classes = list(names)
        # label (1-based) -> index into self.classes, or -1 for labels filtered out.
        self._label_to_class = np.full(len(names) + 1, -1, dtype=np.int64)
        for k, c in enumerate(self.classes):
            self._label_to_class[names.index(c) + 1] = k

        self.session = self.open_session()
        self._read_signature()

    def _read_signature(self) -> None:
        path = self.model_path
        inputs = self.session.get_inputs()
        if len(inputs) != 1:
            self.fail(f"model must have one input (image [3, H, W]), has {len(inputs)}", path)
        self.input_name = inputs[0].name
        shape = inputs[0].shape
        if len(shape) != 3 or (isinstance(shape[0], int) and shape[0] != 3):
            self.fail(f"model input must be image [3, H, W] (the zoo Mask R-CNN layout), is {shape}", path)
        outputs = self.session.get_outputs()
        names = [o.name for o in outputs]
        if {"boxes", "labels", "scores", "masks"} <= set(names):
            self._out_names = ["boxes", "labels", "scores", "masks"]
        elif len(outputs) == 4:
            # The zoo file's outputs are numbered ("6568", ...); their order is boxes, labels,
            # scores, masks.
            self._out_names = names
        else:
            self.fail(f"model must have 4 outputs (boxes, labels, scores, masks), has {len(outputs)}", path)

    def preprocess(self, rgb: np.ndarray) -> tuple[np.ndarray, float, float]:
        """Image (H, W, 3) uint8 RGB -> (input (3, H', W') float32, scale_x, scale_y)."""
        h0, w0 = rgb.shape[:2]
        img = rgb
        if self.min_size > 0:
            # maskrcnn-benchmark's resize: short side to min_size unless the long side passes max_size.
            short, long = min(h0, w0), max(h0, w0)
            ratio = self.min_size / short
            if long * ratio > self.max_size:
                ratio = self.max_size / long
            nw, nh = int(round(w0 * ratio)), int(round(h0 * ratio))
            if (nw, nh) != (w0, h0):
                img = np.asarray(Image.fromarray(rgb).resize((nw, nh), Image.BILINEAR))
        nh, nw = img.shape[:2]
        bgr = img[:, :, ::-1].astype(np.float32) - PIXEL_MEAN_BGR
        ph = int(math.ceil(nh / SIZE_DIVISIBILITY) * SIZE_DIVISIBILITY)
        pw = int(math.ceil(nw / SIZE_DIVISIBILITY) * SIZE_DIVISIBILITY)
        x = np.zeros((3, ph, pw), dtype=np.float32)  # padding is 0 after mean subtraction, as in training
        x[:, :nh, :nw] = bgr.transpose(2, 0, 1)
        return x, nw / w0, nh / h0

    def predict(self, rgb: np.ndarray):
        """Run the model: ``boxes (N, 4)`` image pixels, ``labels (N,)`` index into ``classes``,
        ``scores (N,)``, ``masks (N, H, W)`` bool; best first, at most ``max_detections``."""
        h0, w0 = rgb.shape[:2]
        x, sx, sy = self.preprocess(rgb)
        boxes, labels, scores, masks = self.session.run(self._out_names, {self.input_name: x})
        boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
        labels = np.asarray(labels).reshape(-1).astype(np.int64)
        scores = np.asarray(scores, dtype=np.float64).reshape(-1)
        masks = np.asarray(masks, dtype=np.float32)
        n = len(scores)
        if len(boxes) != n or len(labels) != n or masks.shape[0] != n:
            raise PluginError(
                f"{NAME}: outputs disagree on the number of instances (boxes {len(boxes)}, labels "
                f"{len(labels)}, scores {n}, masks {masks.shape[0]})",
                path=self.model_path,
            )
        masks = masks.reshape(n, masks.shape[-2], masks.shape[-1]) if n else masks.reshape(0, 1, 1)
        if n and (labels.min() < 0 or labels.max() > len(self.label_names)):
            raise PluginError(
                f"{NAME}: model gave label {int(labels.max())} but there are only "
                f"{len(self.label_names)} class names (set 'class_names')",
                path=self.model_path,
            )
        cls = self._label_to_class[np.clip(labels, 0, len(self.label_names))]
        keep = np.flatnonzero((labels > 0) & (cls >= 0) & (scores >= self.score_threshold))
        keep = keep[np.argsort(-scores[keep], kind="stable")][: self.max_detections]
        # Back to the caller's image: the resize scaled x and y separately (integer sizes).
        boxes_img = boxes[keep] / [sx, sy, sx, sy]
        boxes_img[:, [0, 2]] = boxes_img[:, [0, 2]].clip(0, w0)
        boxes_img[:, [1, 3]] = boxes_img[:, [1, 3]].clip(0, h0)
        out_masks = np.zeros((len(keep), h0, w0), dtype=bool)
        for k, i in enumerate(keep):
            out_masks[k] = paste_mask(masks[i], boxes_img[k], h0, w0, self.mask_threshold)
        nonempty = out_masks.reshape(len(keep), h0 * w0).any(axis=1)
        return (
            boxes_img[nonempty].astype(np.float32),
            cls[keep][nonempty],
            scores[keep][nonempty].astype(np.float32),
            out_masks[nonempty],
        )

    def detect(self, frame: Frame) -> list[Detection]:
        """Instances in a frame; each score vector is one-hot at its class, scaled by its score."""
        rgb = frame_rgb(frame, NAME)
        _, labels, scores, masks = self.predict(rgb)
        out = []
        for label, score, mask in zip(labels, scores, masks):
            vec = np.zeros(len(self.classes), dtype=np.float32)
            vec[label] = score
            out.append(Detection(mask=mask, scores=vec))
        return out


@hookimpl
def register_detectors(register):
    register(NAME, MaskRcnnDetector.from_options)

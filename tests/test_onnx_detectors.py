"""ONNX detectors (plugins/onnx_yolo_seg.py, plugins/onnx_maskrcnn.py).

Tiny models built here with the ``onnx`` helper API (Constant outputs of known values) check the
decoding exactly: letterbox, box, class, class-aware NMS, masks through the letterbox / pasted into the
box. One test runs the real int8 YOLOv8n-seg from ../shared/models on a real frame (skipped if absent).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

onnx = pytest.importorskip("onnx")
pytest.importorskip("onnxruntime")
from onnx import TensorProto, helper, numpy_helper  # noqa: E402

from ltc_cli.errors import PluginError  # noqa: E402
from ltc_cli.types import Frame, Intrinsics  # noqa: E402
from ltc_plugins.onnx import maskrcnn as onnx_maskrcnn, yolo_seg as onnx_yolo_seg  # noqa: E402
from ltc_plugins.onnx.maskrcnn import COCO_CLASSES, MaskRcnnDetector, paste_mask  # noqa: E402
from ltc_plugins.onnx.yolo_seg import YoloSegDetector, nms  # noqa: E402
from tests.shared_data import SHARED

REAL_MODEL = SHARED / "models" / "yolov8n-seg_int8.onnx"
DINING_RGB = SHARED / "data" / "dining-room" / "color" / "1.png"


def const_model(path: Path, inp: tuple[str, list], outputs: dict[str, np.ndarray], meta=None) -> Path:
    """An ONNX model whose outputs are constants (the input is accepted and ignored)."""
    nodes, outs = [], []
    for name, arr in outputs.items():
        nodes.append(helper.make_node("Constant", [], [name], value=numpy_helper.from_array(arr, name)))
        dtype = TensorProto.INT64 if arr.dtype == np.int64 else TensorProto.FLOAT
        outs.append(helper.make_tensor_value_info(name, dtype, list(arr.shape)))
    graph = helper.make_graph(
        nodes, "tiny", [helper.make_tensor_value_info(inp[0], TensorProto.FLOAT, inp[1])], outs
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    model.ir_version = 8  # readable by any onnxruntime >= 1.10
    for k, v in (meta or {}).items():
        model.metadata_props.add(key=k, value=v)
    onnx.checker.check_model(model)
    onnx.save(model, str(path))
    return path


def frame_of(rgb: np.ndarray) -> Frame:
    h, w = rgb.shape[:2]
    return Frame(
        key="0", index=0, depth_m=np.ones((h, w), np.float32), T_world_camera=np.eye(4),
        intrinsics=Intrinsics(w, h, 50.0, 50.0, w / 2, h / 2), rgb=rgb,
    )  # fmt: skip


# --------------------------------------------------------------------------------------------------
# YOLO -seg

# Image 64 wide x 48 high into a 32x32 input: scale 0.5, 32x24, padded 4 rows above and below.
IMG_H, IMG_W = 48, 64
YOLO_META = {"names": "{0: 'chair', 1: 'table'}", "imgsz": "[32, 32]", "stride": "32", "task": "segment"}


def yolo_outputs():
    """output0 [1, 4 + 2 + 32, 4] and output1 [1, 32, 8, 8] with known decodings."""
    nc, nm, anchors = 2, 32, 4
    out0 = np.zeros((1, 4 + nc + nm, anchors), np.float32)

    def anchor(a, box, scores, coef0):
        out0[0, 0:4, a] = box
        out0[0, 4 : 4 + nc, a] = scores
        out0[0, 4 + nc, a] = coef0

    # Input box x 8..24, y 12..20 -> image x 16..48, y 16..32.
    anchor(0, (16, 16, 16, 8), (0.9, 0.05), +1.0)  # chair, mask = left half of the prototypes
    anchor(1, (17, 16, 16, 8), (0.6, 0.0), +1.0)  # same chair, lower score: NMS drops it
    anchor(2, (16, 16, 16, 8), (0.1, 0.8), -1.0)  # table on the same box: class-aware NMS keeps it
    anchor(3, (8, 8, 4, 4), (0.1, 0.2), +1.0)  # under the 0.25 threshold
    protos = np.zeros((1, nm, 8, 8), np.float32)
    protos[0, 0, :, :4] = 10.0  # left half of the input (x < 16) -> image x < 32
    protos[0, 0, :, 4:] = -10.0
    return {"output0": out0, "output1": protos}


@pytest.fixture
def yolo_model(tmp_path) -> Path:
    return const_model(tmp_path / "tiny-seg.onnx", ("images", [1, 3, 32, 32]), yolo_outputs(), YOLO_META)


def test_yolo_reads_signature_from_model(yolo_model):
    det = YoloSegDetector.from_options(None, {"model": str(yolo_model)})
    assert det.classes == ["chair", "table"]
    assert det.input_hw == (32, 32) and det.stride == 32


def test_yolo_letterbox(yolo_model):
    det = YoloSegDetector.from_options(None, {"model": str(yolo_model)})
    rgb = np.full((IMG_H, IMG_W, 3), 200, np.uint8)
    x, r, (left, top) = det.letterbox(rgb)
    assert x.shape == (1, 3, 32, 32) and x.dtype == np.float32
    assert (r, left, top) == (0.5, 0, 4)
    np.testing.assert_allclose(x[0, :, :4], 114 / 255)  # padding rows
    np.testing.assert_allclose(x[0, :, 28:], 114 / 255)
    np.testing.assert_allclose(x[0, :, 4:28], 200 / 255, atol=1e-6)


def test_yolo_decodes_box_class_nms_and_mask(yolo_model):
    det = YoloSegDetector.from_options(None, {"model": str(yolo_model)})
    rgb = np.zeros((IMG_H, IMG_W, 3), np.uint8)
    boxes, labels, scores, masks = det.predict(rgb)
    assert labels.tolist() == [0, 1]  # chair then table; the duplicate chair is suppressed
    np.testing.assert_allclose(boxes, [[16, 16, 48, 32], [16, 16, 48, 32]], atol=1e-4)
    np.testing.assert_allclose(scores, [[0.9, 0.05], [0.1, 0.8]], atol=1e-6)  # full score vectors
    assert masks.shape == (2, IMG_H, IMG_W)
    expected_chair = np.zeros((IMG_H, IMG_W), bool)
    expected_chair[16:32, 16:32] = True  # the box, left of the prototypes' edge at image x = 32
    expected_table = np.zeros((IMG_H, IMG_W), bool)
    expected_table[16:32, 32:48] = True
    np.testing.assert_array_equal(masks[0], expected_chair)
    np.testing.assert_array_equal(masks[1], expected_table)

    dets = det.detect(frame_of(rgb))
    assert len(dets) == 2
    np.testing.assert_array_equal(dets[0].mask, expected_chair)
    np.testing.assert_allclose(dets[0].scores, [0.9, 0.05], atol=1e-6)


def test_yolo_options(yolo_model):
    rgb = np.zeros((IMG_H, IMG_W, 3), np.uint8)
    det = YoloSegDetector.from_options(None, {"model": str(yolo_model), "classes": ["table"]})
    assert det.classes == ["table"]
    dets = det.detect(frame_of(rgb))
    assert len(dets) == 1 and dets[0].scores.tolist() == pytest.approx([0.8])
    assert dets[0].mask[16:32, 32:48].all() and dets[0].mask.sum() == 256

    det = YoloSegDetector.from_options(None, {"model": str(yolo_model), "score_threshold": 0.85})
    assert len(det.detect(frame_of(rgb))) == 1
    det = YoloSegDetector.from_options(None, {"model": str(yolo_model), "nms_iou": 0.99})
    assert len(det.detect(frame_of(rgb))) == 3  # IoU of the two chairs is 0.88: both kept
    det = YoloSegDetector.from_options(None, {"model": str(yolo_model), "max_detections": 1})
    assert len(det.detect(frame_of(rgb))) == 1


def test_yolo_scores_summing_over_one_are_scaled(tmp_path):
    outs = yolo_outputs()
    outs["output0"][0, 4:6, 0] = (0.9, 0.6)
    model = const_model(tmp_path / "m.onnx", ("images", [1, 3, 32, 32]), outs, YOLO_META)
    det = YoloSegDetector.from_options(None, {"model": str(model)})
    s = det.detect(frame_of(np.zeros((IMG_H, IMG_W, 3), np.uint8)))[0].scores
    np.testing.assert_allclose(s, [0.6, 0.4], atol=1e-6)  # 0.9 : 0.6, summing to 1


def test_yolo_dynamic_input_uses_imgsz_metadata(tmp_path):
    model = const_model(tmp_path / "dyn.onnx", ("images", [1, 3, "height", "width"]), yolo_outputs(), YOLO_META)
    det = YoloSegDetector.from_options(None, {"model": str(model)})
    assert det.input_hw == (32, 32)
    labels = det.predict(np.zeros((IMG_H, IMG_W, 3), np.uint8))[1]
    assert labels.tolist() == [0, 1]
    det = YoloSegDetector.from_options(None, {"model": str(model), "imgsz": 40})
    assert det.input_hw == (64, 64)  # rounded up to the stride


@pytest.mark.parametrize(
    "options, fragment",
    [
        ({}, "'model' is required"),
        ({"model": "/nonexistent/x.onnx"}, "model file not found"),
        ({"score_threshold": 1.5}, "score_threshold"),
        ({"nms_iou": 0}, "nms_iou"),
        ({"mask_threshold": "high"}, "mask_threshold"),
        ({"max_detections": 0}, "max_detections"),
        ({"threads": 1.5}, "threads"),
        ({"classes": ["sofa"]}, "'sofa'"),
        ({"classes": []}, "classes"),
        ({"scor_threshold": 0.3}, "unknown option"),
    ],
)
def test_yolo_bad_options(yolo_model, options, fragment):
    opts = {"model": str(yolo_model), **options}
    if options == {}:
        opts = {}
    with pytest.raises(PluginError, match=fragment) as err:
        YoloSegDetector.from_options(None, opts)
    if "model" in options:
        assert err.value.path == "/nonexistent/x.onnx"


def test_yolo_names_metadata_is_never_evaluated(tmp_path):
    meta = dict(YOLO_META, names="__import__('os').system('echo pwned')")
    model = const_model(tmp_path / "evil.onnx", ("images", [1, 3, 32, 32]), yolo_outputs(), meta)
    with pytest.raises(PluginError, match="names"):
        YoloSegDetector.from_options(None, {"model": str(model)})


def test_yolo_refuses_detect_models_and_bad_files(tmp_path):
    model = const_model(
        tmp_path / "det.onnx", ("images", [1, 3, 32, 32]), yolo_outputs(), dict(YOLO_META, task="detect")
    )
    with pytest.raises(PluginError, match="seg"):
        YoloSegDetector.from_options(None, {"model": str(model)})
    junk = tmp_path / "junk.onnx"
    junk.write_bytes(b"not a model")
    with pytest.raises(PluginError, match="cannot load") as err:
        YoloSegDetector.from_options(None, {"model": str(junk)})
    assert err.value.path == str(junk)


def test_nms_is_greedy_by_score():
    boxes = np.array([[0, 0, 10, 10], [1, 0, 11, 10], [20, 20, 30, 30]], float)
    assert nms(boxes, np.array([0.5, 0.9, 0.4]), 0.5).tolist() == [1, 2]


def test_real_yolov8n_seg_on_dining_room():
    """The shipped int8 YOLOv8n-seg finds the dining room's furniture with masks of sane size."""
    if not REAL_MODEL.is_file() or not DINING_RGB.is_file():
        pytest.skip("../shared/models/yolov8n-seg_int8.onnx or the dining-room frames are absent")
    from ltc_cli.recordings.images import load_rgb

    det = YoloSegDetector.from_options(None, {"model": str(REAL_MODEL), "threads": 1})
    assert len(det.classes) == 80 and det.input_hw == (320, 320)
    rgb = load_rgb(DINING_RGB)
    frame = frame_of(rgb)
    det.detect(frame)  # warm-up (onnxruntime prepares its kernels on the first run)
    runs = 3
    t0 = time.perf_counter()
    for _ in range(runs):
        dets = det.detect(frame)
    ms = (time.perf_counter() - t0) / runs * 1000
    names = [det.classes[int(np.argmax(d.scores))] for d in dets]
    print(f"\nyolov8n-seg int8, 320x320, 1 thread: {ms:.0f} ms/frame (640x480 in, incl. decoding); {names}")

    assert "chair" in names and "dining table" in names
    for d, name in zip(dets, names):
        assert d.mask.shape == rgb.shape[:2] and d.mask.dtype == bool
        assert d.scores.shape == (80,) and d.scores.max() >= 0.25
        area = int(d.mask.sum())
        if name == "chair":
            assert 1_000 < area < 0.25 * rgb.shape[0] * rgb.shape[1]
        if name == "dining table":
            assert 10_000 < area < 0.6 * rgb.shape[0] * rgb.shape[1]
    # The table is the big, low object in the middle of this view.
    table = dets[names.index("dining table")].mask
    v, u = np.nonzero(table)
    assert v.mean() > rgb.shape[0] / 2 and 200 < u.mean() < 560


# --------------------------------------------------------------------------------------------------
# Mask R-CNN (ONNX model zoo layout)


def maskrcnn_outputs(scale_x=1.0, scale_y=1.0):
    """Instances in the *input's* pixels (the image after the detector's resize)."""
    boxes = np.array(
        [[16, 8, 48, 40], [0, 0, 10, 10], [2, 30, 20, 46]], np.float32
    ) * np.array([scale_x, scale_y, scale_x, scale_y], np.float32)
    labels = np.array([57, 61, 1], np.int64)  # chair, dining table, person (1-based COCO)
    scores = np.array([0.9, 0.3, 0.7], np.float32)
    masks = np.zeros((3, 1, 28, 28), np.float32)
    masks[0, 0, :, :14] = 1.0  # the chair fills the left half of its box
    masks[1:, 0] = 1.0
    return {"boxes": boxes, "labels": labels, "scores": scores, "masks": masks}


def zoo_names(outputs):
    # The zoo's file names its outputs by number, in this order.
    return dict(zip(["6568", "6570", "6572", "6887"], outputs.values()))


def test_maskrcnn_pastes_mask_into_box(tmp_path):
    model = const_model(tmp_path / "mrcnn.onnx", ("image", [3, "height", "width"]), zoo_names(maskrcnn_outputs()))
    det = MaskRcnnDetector.from_options(None, {"model": str(model), "min_size": 0})
    assert det.classes == COCO_CLASSES and len(COCO_CLASSES) == 80
    rgb = np.zeros((IMG_H, IMG_W, 3), np.uint8)
    boxes, labels, scores, masks = det.predict(rgb)
    # The table (0.3) is under the 0.5 threshold; best first.
    assert [det.classes[k] for k in labels] == ["chair", "person"]
    np.testing.assert_allclose(scores, [0.9, 0.7])
    np.testing.assert_allclose(boxes[0], [16, 8, 48, 40])
    expected = np.zeros((IMG_H, IMG_W), bool)
    expected[8:40, 16:32] = True  # rows of the box, left half of its columns
    np.testing.assert_array_equal(masks[0], expected)
    assert masks[1][30:46, 2:20].all() and masks[1].sum() == 16 * 18

    dets = det.detect(frame_of(rgb))
    assert len(dets) == 2
    chair = COCO_CLASSES.index("chair")
    assert dets[0].scores.shape == (80,)
    assert dets[0].scores[chair] == pytest.approx(0.9) and dets[0].scores.sum() == pytest.approx(0.9)
    np.testing.assert_array_equal(dets[0].mask, expected)


def test_maskrcnn_resize_scales_back(tmp_path):
    # Default min_size 800: a 64x48 image becomes 1067x800 (scale 16.67), padded to 1088x800.
    sx, sy = 1067 / 64, 800 / 48
    model = const_model(
        tmp_path / "mrcnn.onnx", ("image", [3, "height", "width"]), zoo_names(maskrcnn_outputs(sx, sy))
    )
    det = MaskRcnnDetector.from_options(None, {"model": str(model)})
    x, got_sx, got_sy = det.preprocess(np.zeros((IMG_H, IMG_W, 3), np.uint8))
    assert x.shape == (3, 800, 1088) and (got_sx, got_sy) == (sx, sy)
    boxes, labels, _, masks = det.predict(np.zeros((IMG_H, IMG_W, 3), np.uint8))
    np.testing.assert_allclose(boxes[0], [16, 8, 48, 40], atol=1e-3)
    assert masks[0][8:40, 16:32].all() and masks[0].sum() == 32 * 16


def test_maskrcnn_preprocess_is_bgr_minus_mean_padded(tmp_path):
    model = const_model(tmp_path / "m.onnx", ("image", [3, "height", "width"]), maskrcnn_outputs())
    det = MaskRcnnDetector.from_options(None, {"model": str(model), "min_size": 0})
    rgb = np.zeros((IMG_H, 50, 3), np.uint8)
    rgb[:] = (10, 20, 30)
    x, _, _ = det.preprocess(rgb)
    assert x.shape == (3, 64, 64)  # 48x50 padded to multiples of 32
    np.testing.assert_allclose(x[:, 0, 0], [30 - 102.9801, 20 - 115.9465, 10 - 122.7717], atol=1e-4)
    assert np.all(x[:, 48:, :] == 0) and np.all(x[:, :, 50:] == 0)


def test_maskrcnn_classes_and_names_options(tmp_path):
    outs = maskrcnn_outputs()
    model = const_model(tmp_path / "m.onnx", ("image", [3, "height", "width"]), outs)
    rgb = np.zeros((IMG_H, IMG_W, 3), np.uint8)
    det = MaskRcnnDetector.from_options(
        None, {"model": str(model), "min_size": 0, "classes": ["person", "dining table"], "score_threshold": 0.2}
    )
    dets = det.detect(frame_of(rgb))
    assert det.classes == ["person", "dining table"]
    assert [d.scores.tolist() for d in dets] == [pytest.approx([0.7, 0.0]), pytest.approx([0.0, 0.3])]

    names = [f"c{i}" for i in range(1, 62)]
    det = MaskRcnnDetector.from_options(None, {"model": str(model), "min_size": 0, "class_names": names})
    assert [det.classes[k] for k in det.predict(rgb)[1]] == ["c57", "c1"]
    det = MaskRcnnDetector.from_options(None, {"model": str(model), "min_size": 0, "class_names": ["a", "b"]})
    with pytest.raises(PluginError, match="class names"):
        det.predict(rgb)
    with pytest.raises(PluginError, match="'sofa'"):
        MaskRcnnDetector.from_options(None, {"model": str(model), "classes": ["sofa"]})
    with pytest.raises(PluginError, match="model file not found"):
        MaskRcnnDetector.from_options(None, {"model": str(tmp_path / "none.onnx")})


def test_maskrcnn_no_instances(tmp_path):
    outs = {
        "boxes": np.zeros((0, 4), np.float32),
        "labels": np.zeros((0,), np.int64),
        "scores": np.zeros((0,), np.float32),
        "masks": np.zeros((0, 1, 28, 28), np.float32),
    }
    model = const_model(tmp_path / "m.onnx", ("image", [3, "height", "width"]), outs)
    det = MaskRcnnDetector.from_options(None, {"model": str(model), "min_size": 0})
    assert det.detect(frame_of(np.zeros((IMG_H, IMG_W, 3), np.uint8))) == []


def test_paste_mask_full_box():
    m = paste_mask(np.ones((28, 28), np.float32), (3.0, 2.0, 13.0, 9.0), 12, 16, 0.5)
    expected = np.zeros((12, 16), bool)
    expected[2:9, 3:13] = True
    np.testing.assert_array_equal(m, expected)


def test_registered_names():
    got = {}
    for module in (onnx_yolo_seg, onnx_maskrcnn):
        module.register_detectors(register=lambda name, f: got.setdefault(name, f))
    assert sorted(got) == ["onnx-maskrcnn", "onnx-yolo-seg"]

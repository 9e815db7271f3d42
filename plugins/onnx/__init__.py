"""ONNX detectors on onnxruntime's CPU: ``onnx-yolo-seg`` (:mod:`.yolo_seg`) and ``onnx-maskrcnn``
(:mod:`.maskrcnn`), sharing options, session and mask sampling (:mod:`.common`). Each module is
its own entry point."""

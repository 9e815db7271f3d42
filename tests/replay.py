"""Plugins for passes over one real recording (tests/test_real_revisits.py and
benchmarks/bench_real.py): the shared model detecting each frame once and replaying it, and a
reader that drives a recording in reverse order, at a lower frame rate, or along part of it."""

from __future__ import annotations

from dataclasses import replace

from ltc_cli import plugins


class Replay:
    """Wraps the onnx-yolo-seg detector: detects each frame once, then replays (the detector is
    deterministic, so later passes cost only the mapping)."""

    thread_safe = True
    store: dict = {}

    def __init__(self, recording, options):
        self.inner = plugins.get("detectors", "onnx-yolo-seg").factory(recording, options)
        self.classes = self.inner.classes
        self.identity = (options.get("model"), recording.identity)  # one store for both shared models

    def detect(self, frame):
        key = (self.identity, frame.key)
        if key not in self.store:
            self.store[key] = self.inner.detect(frame)
        return self.store[key]


class Reordered:
    """Any recording with its frames in reverse order (the same route driven backwards), or every
    ``step``-th frame of it from frame ``start`` (a lower frame rate; with another start, the same
    route driven again and seen in other images), or the part ``span`` of it (fractions of its
    frames: a drive along part of the route)."""

    def __init__(self, reverse: bool = False, step: int = 1, start: int = 0, span: tuple = (0.0, 1.0)):
        self.reverse, self.step, self.start, self.span = reverse, step, start, span

    def sniff(self, path) -> bool:
        return False

    def open(self, path, options):
        from ltc_cli.recordings.open import open_recording

        rec = open_recording(path)
        n = len(rec.frames)
        frames = list(rec.frames)[round(self.span[0] * n):round(self.span[1] * n)]
        frames = list(reversed(frames)) if self.reverse else frames
        return replace(rec, frames=frames[self.start::self.step])

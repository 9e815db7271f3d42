"""Plugins for passes over one real recording (tests/test_real_revisits.py and
benchmarks/bench_real.py): the shared model detecting each frame once and replaying it (or a
weaker detector's share of its detections), a reader that drives a recording in reverse order, at
a lower frame rate, or along part of it, and one that puts a localiser's drift on its poses."""

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


def weaker(seed: int, share: float) -> type:
    """A :class:`Replay` detector that misses each detection with probability ``share``, drawn from
    ``seed`` and the frame's key: a weaker detector, as the same route would get from a smaller
    model or in worse light (misses without a pattern: the simulator's are correlated)."""

    def detect(self, frame):
        import zlib

        import numpy as np

        found = Replay.detect(self, frame)
        draw = np.random.default_rng([seed, zlib.crc32(frame.key.encode())]).uniform(size=len(found))
        return [d for d, u in zip(found, draw) if u >= share]

    return type(f"Weaker{seed}", (Replay,), {"detect": detect})


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


class Drifted:
    """Any recording with a localiser's error on its poses: the realistic simulator's slow drift and
    jitter (``ltc_cli.tools.simulate.drift.pose_errors``: 4 cm and 1.5 degrees, 5 mm and 0.2
    degrees), drawn from ``seed`` with a correlation of ``frames`` frames. The images stay where
    they were taken, as a robot's localiser reports a pose off the true one; the recording's world
    is taken as z-up (tum-fr1-rpy's is within a few degrees), which is where the drift is largest
    (x, y and the yaw)."""

    def __init__(self, seed: int, frames: float = 60.0):
        self.seed, self.frames = seed, frames

    def sniff(self, path) -> bool:
        return False

    def open(self, path, options):
        import numpy as np
        from scipy.spatial.transform import Rotation

        from ltc_cli.recordings.open import open_recording
        from ltc_cli.tools.simulate.drift import pose_errors
        from ltc_cli.tools.simulate.options import check_options

        rec = open_recording(path)
        opts = {**check_options({}, "realistic"), "drift_frames": self.frames}
        d_pos, d_rot = pose_errors(np.random.default_rng(self.seed), len(rec.frames), opts)
        R_err = Rotation.from_rotvec(d_rot).as_matrix()

        return replace(rec, frames=[moved(ref, R_err[k], d_pos[k]) for k, ref in enumerate(rec.frames)])


def moved(ref, R_err, d_pos, key: str | None = None):
    """``ref`` whose loaded pose is off by a turn ``R_err`` (3, 3) of the camera about its own
    centre and a shift ``d_pos`` (3,), under the frame id ``key`` (default its own)."""
    def off(T):
        T = T.copy()
        T[:3, :3] = R_err @ T[:3, :3]
        T[:3, 3] += d_pos
        return T

    def load():
        frame = ref.load()
        frame.T_world_camera = off(frame.T_world_camera)
        return frame
    pose = None if ref.pose is None else (lambda: off(ref.pose()))
    return replace(ref, key=ref.key if key is None else key, load=load, pose=pose)


class Stopped:
    """Any recording with the camera stopped after the frames at positions ``at``: each followed by
    ``n`` copies of itself (its images under new frame ids; the loaded frame keeps its key, so a
    :class:`Replay` detector replays its detections), as a robot that waits at a door or behind a
    person records one view for seconds. With ``jitter`` (metres, degrees), each
    copy's pose is off by that much, drawn from ``seed``: a localiser's noise while standing."""

    def __init__(self, at: tuple, n: int, jitter: tuple | None = None, seed: int = 0):
        self.at, self.n, self.jitter, self.seed = set(at), n, jitter, seed

    def sniff(self, path) -> bool:
        return False

    def open(self, path, options):
        import numpy as np
        from scipy.spatial.transform import Rotation

        from ltc_cli.recordings.open import open_recording

        rec = open_recording(path)
        rng = np.random.default_rng(self.seed)

        def copy(ref, k):
            if self.jitter is None:
                return replace(ref, key=f"{ref.key}-stop{k}")
            d_pos = rng.normal(0.0, self.jitter[0], 3)
            R_err = Rotation.from_rotvec(np.radians(rng.normal(0.0, self.jitter[1], 3))).as_matrix()
            return moved(ref, R_err, d_pos, key=f"{ref.key}-stop{k}")

        frames = []
        for i, ref in enumerate(rec.frames):
            frames.append(ref)
            if i in self.at:
                frames += [copy(ref, k) for k in range(self.n)]
        return replace(rec, frames=frames)

"""A still camera's frames are not mapped (``frames.still_move`` / ``frames.still_turn``,
ltc_cli/ingest/keyframes.py): the test by hand, the ingest that records them as done without
mapping or detecting them, and a resume that goes on from the last mapped pose."""

import dataclasses
import json
import shutil
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.spatial.transform import Rotation

from ltc_cli import hookimpl, plugins
from ltc_cli.cli import cli
from ltc_cli.config import defaults, load_config
from ltc_cli.ingest.keyframes import StillFrames, is_still, turn_degrees
from ltc_cli.ingest.prefetch import Prefetch
import ltc_cli.ingest.session as session_module
from ltc_cli.ingest.session import ingest
from ltc_cli.map.store import load_map
from ltc_plugins.recorded import RecordedDetector
from tests.test_revisit import assert_same_map

LAP1 = Path(__file__).resolve().parent.parent / "sample_data" / "lap1"
N_FRAMES = 76
STILL_AFTER, COPIES = "000010", 5


def pose(xyz=(0.0, 0.0, 0.0), rotvec_deg=(0.0, 0.0, 0.0)) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(np.radians(rotvec_deg)).as_matrix()
    T[:3, 3] = xyz
    return T


def test_still_by_hand():
    ref = pose((1.0, 2.0, 0.5))
    # 0.015 m and 1.9 degrees are under 0.02 m and 2 degrees: still; 0.025 m or 2.1 degrees is a move.
    assert is_still(ref, pose((1.015, 2.0, 0.5)), 0.02, 2.0)
    assert not is_still(ref, pose((1.0, 2.025, 0.5)), 0.02, 2.0)
    axis = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)  # a roll and pitch together: the angle, not per axis
    assert is_still(ref, pose((1.0, 2.0, 0.5), 1.9 * axis), 0.02, 2.0)
    assert not is_still(ref, pose((1.0, 2.0, 0.5), 2.1 * axis), 0.02, 2.0)
    # The first frame, or a setting of null, is never still (every frame mapped, the paper).
    assert not is_still(None, ref, 0.02, 2.0)
    assert not is_still(ref, ref, None, 2.0) and not is_still(ref, ref, 0.02, None)


def test_turn_degrees_is_the_rotation_angle():
    rng = np.random.default_rng(3)
    for _ in range(50):  # against scipy's angle of R_a^T R_b
        a, b = Rotation.random(random_state=rng), Rotation.random(random_state=rng)
        assert turn_degrees(a.as_matrix(), b.as_matrix()) == pytest.approx(np.degrees((a.inv() * b).magnitude()),
                                                                             abs=1e-6)


def test_reference_is_the_last_mapped_pose_of_each_recording():
    still = StillFrames({"still_move": 0.02, "still_turn": 2.0}, 2)
    assert not still.still(0, pose())  # no frame mapped yet
    still.mapped(0, pose())
    # Creeping 1.5 cm a frame: the second step is 3 cm from the last mapped pose, not 1.5 from the last.
    assert still.still(0, pose((0.015, 0, 0)))
    assert not still.still(0, pose((0.03, 0, 0)))
    assert not still.still(1, pose())  # the other recording has its own
    resumed = StillFrames({"still_move": 0.02, "still_turn": 2.0}, 2, still.refs)
    assert resumed.still(0, pose((0.015, 0, 0)))


@pytest.mark.parametrize("text,kept", [
    (json.dumps([np.eye(4).tolist(), None]), [True, False]),
    ("", [False, False]),  # a row written before ltc kept the poses
    ("not json", [False, False]),
    (json.dumps({"0": np.eye(4).tolist()}), [False, False]),
    (json.dumps([[[1, 2], [3, 4]], [[float("nan")] * 4] * 4]), [False, False]),  # a damaged row
])
def test_a_session_rows_poses_are_read_or_dropped(text, kept):
    still = StillFrames.resumed({"still_move": 0.02, "still_turn": 1.0}, 2, text)
    # A kept reference makes the identity pose still; a dropped one maps the next frame.
    assert [still.still(k, np.eye(4)) for k in range(2)] == kept


def with_still_copies(root: Path, copies: int = COPIES) -> Path:
    """sample_data/lap1 with the camera stopped after frame STILL_AFTER for ``copies`` frames: the
    same images, detections and pose again under new frame ids."""
    rec = root / "still"
    shutil.copytree(LAP1, rec)
    lines = []
    for line in (LAP1 / "poses.txt").read_text().splitlines():
        lines.append(line)
        if line.split()[0] == STILL_AFTER:
            for k in range(copies):
                fid = f"{STILL_AFTER}s{k}"
                lines.append(line.replace(STILL_AFTER, fid, 1))
                for sub, ext in (("rgb", "png"), ("depth", "png"), ("detections", "json")):
                    shutil.copy(LAP1 / sub / f"{STILL_AFTER}.{ext}", rec / sub / f"{fid}.{ext}")
    (rec / "poses.txt").write_text("\n".join(lines) + "\n")
    return rec


def poses_unknown(open_recording):
    """``open_recording`` whose frames do not tell their poses before loading (a plugin reader's)."""
    def opened(*args, **kwargs):
        rec = open_recording(*args, **kwargs)
        return dataclasses.replace(rec, frames=[dataclasses.replace(r, pose=None) for r in rec.frames])
    return opened


def test_still_frames_are_done_not_mapped(tmp_path):
    rec = with_still_copies(tmp_path)
    s = ingest([rec], tmp_path / "still.h5", defaults())
    # The sample's camera moves 7 cm or more between frames: only the copies are still.
    assert (s.frames_done, s.frames_still) == (N_FRAMES, COPIES)
    smap = load_map(tmp_path / "still.h5")
    assert len(smap.frame_keys) == N_FRAMES + COPIES and smap.sessions[0]["frames_still"] == COPIES
    # Every frame mapped, the paper: the copies are five more observations of what frame 10 saw.
    off = ingest([rec], tmp_path / "every.h5", load_config(None, ["frames.still_move=null"]))
    assert (off.frames_done, off.frames_still) == (N_FRAMES + COPIES, 0)
    n_det = {m: load_map(tmp_path / m).objects.columns()["n_det"].sum() for m in ("still.h5", "every.h5")}
    assert n_det["every.h5"] > n_det["still.h5"]
    # A re-run changes nothing: the still frames are in the map.
    again = ingest([rec], tmp_path / "still.h5", defaults())
    assert (again.frames_done, again.frames_still, again.frames_already) == (0, 0, N_FRAMES + COPIES)


class Counting(RecordedDetector):
    """The recorded detector, keeping the keys of the frames it was asked to detect."""

    keys: list = []

    def detect(self, frame):
        Counting.keys.append(frame.key)
        return super().detect(frame)


class CountingPlugin:
    @hookimpl
    def register_detectors(self, register):
        register("counting-recorded", Counting.from_options)


@pytest.fixture
def counting():
    plugins.register_plugin(CountingPlugin(), name="test-counting")
    Counting.keys = []
    yield Counting.keys
    plugins.unregister_plugin("test-counting")


@pytest.mark.parametrize("jobs", [1, 2])
def test_still_frames_are_not_detected(tmp_path, counting, jobs):
    rec = with_still_copies(tmp_path)
    s = ingest([rec], tmp_path / "m.h5", load_config(None, ["detector.name=counting-recorded"]), jobs=jobs)
    assert (s.frames_done, s.frames_still) == (N_FRAMES, COPIES)
    # One at a time, a still frame is known before its detection; with threads ahead, the calling
    # thread judges each loaded frame in order and has only the kept ones detected.
    assert {f"{STILL_AFTER}s{k}" for k in range(COPIES)}.isdisjoint(counting)
    assert sorted(counting) == sorted(set(counting)) and len(counting) == N_FRAMES


@pytest.mark.parametrize("jobs", [1, 2])
@pytest.mark.parametrize("poses_known", [True, False])
def test_a_still_frame_whose_pose_is_known_is_never_read(tmp_path, monkeypatch, jobs, poses_known):
    """The copies' images are damaged: read, each is a bad frame (skipped); judged by the pose the
    reader knows before reading the images (ltc-recording's poses.txt), none is read."""
    rec = with_still_copies(tmp_path)
    for k in range(COPIES):
        (rec / "depth" / f"{STILL_AFTER}s{k}.png").write_bytes(b"not a png")
    if not poses_known:
        monkeypatch.setattr(session_module, "open_recording", poses_unknown(session_module.open_recording))
    s = ingest([rec], tmp_path / "m.h5", defaults(), jobs=jobs)
    expect = (N_FRAMES, COPIES, 0) if poses_known else (N_FRAMES, 0, COPIES)
    assert (s.frames_done, s.frames_still, s.frames_skipped) == expect


def test_a_frame_kept_ahead_and_not_mapped_leaves_the_map_as_one_at_a_time(tmp_path, counting):
    """Frame 10's detections are broken: it is skipped, so the session's last mapped frame is frame
    9, and the first still copy of frame 10 (7 cm from frame 9) is mapped. The look-ahead kept frame
    10 and judged that copy still by it; the session detects it then, and the map is the one a
    run without look-ahead makes."""
    rec = with_still_copies(tmp_path)
    (rec / "detections" / f"{STILL_AFTER}.json").write_text("{")
    cfg = load_config(None, ["detector.name=counting-recorded"])
    one = ingest([rec], tmp_path / "one.h5", cfg)
    detected_one = sorted(counting)
    counting.clear()
    two = ingest([rec], tmp_path / "two.h5", cfg, jobs=2)
    assert (one.frames_done, one.frames_skipped, one.frames_still) == (N_FRAMES, 1, COPIES - 1)
    assert (two.frames_done, two.frames_skipped, two.frames_still) == (N_FRAMES, 1, COPIES - 1)
    assert_same_map(tmp_path / "one.h5", tmp_path / "two.h5")
    assert f"{STILL_AFTER}s0" in detected_one and sorted(counting) == detected_one


def test_interrupted_among_still_frames_resumes_from_the_last_mapped_pose(tmp_path):
    rec = with_still_copies(tmp_path)
    ref = tmp_path / "ref.h5"
    ingest([rec], ref, defaults())
    m = tmp_path / "m.h5"
    done = []
    # Stop right after frame 10 is mapped, before its still copies: the resumed run must know frame
    # 10's pose, which only the session row keeps.
    s = ingest([rec], m, defaults(), checkpoint_every=4, on_frame=lambda summary: done.append(1),
               should_stop=lambda: len(done) >= 11)
    assert s.interrupted and (s.frames_done, s.frames_still) == (11, 0)
    s2 = ingest([rec], m, defaults())
    assert (s2.frames_done, s2.frames_still, s2.frames_already) == (N_FRAMES - 11, COPIES, 11)
    assert_same_map(ref, m)
    assert load_map(m).sessions[0]["frames_still"] == COPIES


def test_summary_line_and_info_say_how_many_were_still(tmp_path):
    rec = with_still_copies(tmp_path)
    m = tmp_path / "m.h5"
    r = CliRunner().invoke(cli, ["ingest", str(rec), "--map", str(m)])
    assert r.exit_code == 0, r.output
    assert f"{N_FRAMES} frames ingested, 0 skipped, {COPIES} still (the camera had not moved), 0 already" in r.output
    info = CliRunner().invoke(cli, ["info", str(m)])
    assert f"{N_FRAMES} frames (0 skipped, {COPIES} still)" in info.output


class Ref:
    """A frame reference whose load gives a frame with a pose and nothing else."""

    def __init__(self, key: str, T: np.ndarray):
        self.key, self.index, self.T = key, int(key), T

    def load(self):
        return SimpleNamespace(key=self.key, T_world_camera=self.T)


class KeyDetector:
    needs_rgb, thread_safe = False, True

    def __init__(self):
        self.keys: list = []

    def detect(self, frame):
        self.keys.append(frame.key)
        return [frame.key]


def look_ahead(ref_type) -> tuple:
    """(refs, detector, still frames, look-ahead) over ten frames 5 cm apart, but frames 3-5 stand
    where frame 2 stands."""
    xs = [0.0, 0.05, 0.1, 0.1, 0.1, 0.1, 0.15, 0.2, 0.25, 0.3]
    refs = [ref_type(str(k), pose((x, 0.0, 0.0))) for k, x in enumerate(xs)]
    det = KeyDetector()
    still = StillFrames({"still_move": 0.02, "still_turn": 1.0}, 1)
    return refs, det, still, Prefetch(refs, [r.key for r in refs], set(), det, jobs=2, keep=still.judge_ahead(0))


def test_the_look_ahead_judges_in_order_and_holds_its_window():
    refs, det, _, ahead = look_ahead(Ref)
    got = []
    try:
        for ref in refs:
            frame, dets, *_ = ahead.take(ref)
            got.append(dets)
            # Never more frames loading or loaded ahead than the window (2 x jobs).
            assert len(ahead.pending) + len(ahead.judged) <= ahead.lookahead
    finally:
        ahead.close()
    assert got == [["0"], ["1"], ["2"], None, None, None, ["6"], ["7"], ["8"], ["9"]]
    assert sorted(det.keys) == ["0", "1", "2", "6", "7", "8", "9"]


class PosedRef(Ref):
    """A frame reference that knows its pose before loading, and counts its loads."""

    loads: list = []

    def pose(self):
        return self.T

    def load(self):
        PosedRef.loads.append(self.key)
        return super().load()


def test_the_look_ahead_never_loads_a_still_frame_whose_pose_it_knows():
    PosedRef.loads = []
    refs, det, still, ahead = look_ahead(PosedRef)
    got = []
    try:
        for ref in refs:
            if not still.still(0, ref.pose()):  # the session's own judgement, before it asks
                frame, dets, *_ = ahead.take(ref)
                still.mapped(0, frame.T_world_camera)
                got.append(dets)
    finally:
        ahead.close()
    assert got == [["0"], ["1"], ["2"], ["6"], ["7"], ["8"], ["9"]]
    assert sorted(PosedRef.loads) == sorted(det.keys) == ["0", "1", "2", "6", "7", "8", "9"]


def test_check_counts_the_still_frames_and_warns_of_a_camera_fixed_in_place(tmp_path):
    rec = with_still_copies(tmp_path)
    r = CliRunner().invoke(cli, ["check", str(rec)])
    assert r.exit_code == 0, r.output
    assert (f"still        {COPIES} frames, not mapped: the camera moved under 0.02 m and turned under 1 degree "
            "since the last frame kept") in r.output
    assert r.output.rstrip().endswith("ready to ingest")
    doc = json.loads(CliRunner().invoke(cli, ["check", str(rec), "--json"]).stdout)
    counted = doc["still_frames"]
    assert tuple(counted.pop(k) for k in ("reach_m", "reach_deg")) == pytest.approx(reach_of(rec / "poses.txt"), abs=1e-3)
    assert counted == {"still": COPIES, "unknown": 0, "move_m": 0.02, "turn_deg": 1.0}
    # A frame without a pose: an ingest skips it, and the check says so.
    poses = (rec / "poses.txt").read_text().splitlines()
    poses[3] = poses[3].split()[0] + " nan nan nan 0 0 0 1"
    (rec / "poses.txt").write_text("\n".join(poses) + "\n")
    doc = json.loads(CliRunner().invoke(cli, ["check", str(rec), "--json"]).stdout)
    assert (doc["still_frames"]["still"], doc["still_frames"]["unknown"]) == (COPIES, 1)
    # The camera standing at frame 10 for 80 frames, against 76 that move: most are still, but it
    # is a robot that waits and drives on, not a camera fixed in place: no warning.
    waits = with_still_copies(tmp_path / "waits", copies=80)
    r = CliRunner().invoke(cli, ["check", str(waits)])
    assert "still        80 frames, not mapped" in r.output and r.output.rstrip().endswith("ready to ingest")


def reach_of(poses_txt: Path) -> tuple:
    """A second reckoning of how far a recording's camera went from its first pose (m, degrees):
    scipy's rotation magnitude of R_first^T R, over poses.txt."""
    rows = np.array([[float(v) for v in line.split()[1:]] for line in poses_txt.read_text().splitlines()])
    turns = (Rotation.from_quat(rows[0, 3:]).inv() * Rotation.from_quat(rows[:, 3:])).magnitude()
    return float(np.linalg.norm(rows[:, :3] - rows[0, :3], axis=1).max()), float(np.degrees(turns.max()))


def fixed_camera(root: Path, copies: int, step: float = 0.004) -> Path:
    """Frame STILL_AFTER of sample_data/lap1 and ``copies`` copies of it, as from a camera fixed in
    place whose localiser jitters: copy k stands (k % 3) * ``step`` metres along x from it."""
    rec = with_still_copies(root, copies=copies)
    lines = [line for line in (rec / "poses.txt").read_text().splitlines() if line.startswith(STILL_AFTER)]
    for k in range(1, len(lines)):
        fields = lines[k].split()
        fields[1] = repr(float(fields[1]) + (k - 1) % 3 * step)
        lines[k] = " ".join(fields)
    (rec / "poses.txt").write_text("\n".join(lines) + "\n")
    for image in [*(rec / "rgb").iterdir(), *(rec / "depth").iterdir()]:  # only frames with a pose line
        if not image.stem.startswith(STILL_AFTER):
            image.unlink()
    return rec


FIXED_LINE = ("{n} of {total} frames {are} still (the camera moved under 0.02 m and turned under 1 degree since the "
              "last frame kept) and {would} mapped: the camera never left 0.1 m and 5 degrees of its first pose. "
              "ltc maps a moving camera's route and confirms an object only from two distinct views; for a camera "
              "fixed in place, see README.md, 'A camera fixed in place'")
#: README.md, 'A camera fixed in place'.
FIXED_SETTINGS = ["--set", "frames.still_move=null", "--set", "maintenance.min_detection_views=1",
                  "--set", "maintenance.nondet_min_move=null", "--set", "maintenance.nondet_min_turn=null"]


def test_a_camera_fixed_in_place_is_warned_of_by_check_and_ingest(tmp_path):
    fixed = fixed_camera(tmp_path / "fixed", copies=40)
    # By hand: the copies stand 0, 4 and 8 mm from the first frame (under 2 cm): all 40 are still,
    # and the camera went 8 mm from its first pose, not turning.
    assert reach_of(fixed / "poses.txt") == pytest.approx((0.008, 0.0), abs=1e-9)
    r = CliRunner().invoke(cli, ["check", str(fixed)])
    assert "warning: " + FIXED_LINE.format(n=40, total=41, are="are", would="would not be") in r.output
    assert r.output.rstrip().endswith("1 warning (above)")
    r = CliRunner().invoke(cli, ["check", str(fixed), "--set", "frames.still_move=null"])
    assert "still        none: every frame is mapped (frames.still_move or still_turn is null)" in r.output
    assert r.output.rstrip().endswith("ready to ingest")
    m = tmp_path / "m.h5"
    r = CliRunner().invoke(cli, ["ingest", str(fixed), "--map", str(m)])
    assert r.exit_code == 0, r.output
    assert f"warning: {fixed}: " + FIXED_LINE.format(n=40, total=41, are="were", would="were not") in r.stderr
    assert "1 frame ingested, 0 skipped, 40 still" in r.stdout
    assert "objects 2 created, 0 merged, 2 removed; 0 in the map" in r.stdout  # one view confirms nothing
    # The README's settings for a fixed camera: every frame mapped, and an object kept from one
    # view. The frame's recorded detections name two things (a potted plant, a couch).
    r = CliRunner().invoke(cli, ["ingest", str(fixed), "--map", str(tmp_path / "all.h5"), *FIXED_SETTINGS])
    assert r.exit_code == 0 and "41 frames ingested" in r.stdout and "warning" not in r.stderr
    want = sorted(d["class"] for d in json.loads((LAP1 / "detections" / f"{STILL_AFTER}.json").read_text())["instances"])
    smap = load_map(tmp_path / "all.h5")
    assert sorted(smap.classes[int(np.argmax(smap.objects.scores[i, :-1]))] for i in smap.active_rows()) == want
    # 12 cm of jitter: the camera left 0.1 m of its first pose, so it is not taken for a fixed one.
    moved = fixed_camera(tmp_path / "moved", copies=40, step=0.06)
    r = CliRunner().invoke(cli, ["check", str(moved)])
    assert "fixed in place" not in r.output and r.output.rstrip().endswith("ready to ingest")


@pytest.mark.parametrize("known", [True, False])
def test_a_resumed_ingest_judges_a_fixed_camera_by_all_its_frames(tmp_path, monkeypatch, known):
    """Interrupted after 30 of the fixed camera's 41 frames: the resumed run itself sees 11 (all
    still), under half. It judges the frames the first run did again from their poses, and warns as
    an uninterrupted ingest does; a reader that does not tell poses before loading gives no warning
    (from 11 frames it could be wrong either way). Run once more, the finished ingest is a no-op, and
    says nothing of the camera again."""
    fixed = fixed_camera(tmp_path / "fixed", copies=40)
    if not known:
        monkeypatch.setattr(session_module, "open_recording", poses_unknown(session_module.open_recording))
    m, warned, asked = tmp_path / "m.h5", [], []
    s = ingest([fixed], m, defaults(), warn=warned.append, should_stop=lambda: asked.append(1) or len(asked) > 30)
    assert s.interrupted and (s.frames_done, s.frames_still) == (1, 29) and warned == []
    s = ingest([fixed], m, defaults(), warn=warned.append)
    assert not s.interrupted and (s.frames_done, s.frames_still, s.frames_already) == (0, 11, 30)
    line = f"{fixed}: " + FIXED_LINE.format(n=40, total=41, are="were", would="were not")
    assert warned == ([line] if known else [])
    warned.clear()
    s = ingest([fixed], m, defaults(), warn=warned.append)
    assert (s.frames_done, s.frames_still, s.frames_already) == (0, 0, 41) and warned == []

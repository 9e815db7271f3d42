"""Poses that do not fit the depth: consecutive frames' agreement worked out by hand, each wrong
convention (world-to-camera, OpenGL axes, x-forward axes, quaternions w first) told apart from the
right one on the sample recording and on tum-fr1-rpy, the ingest's one-line warning that names the
reader option, and ``-r pose_convention=NAME`` reading them right."""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from scipy.spatial.transform import Rotation

from ltc_cli.cli import cli
from ltc_cli.geometry.camera import invert_pose
from ltc_cli.geometry.pose_agreement import READINGS, agreement, judge_poses
from ltc_cli.map.store import load_map
from ltc_cli.recordings.open import open_recording
from ltc_cli.recordings.writer import RecordingWriter
from ltc_cli.types import Intrinsics
from tests.shared_data import SHARED

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "sample_data" / "lap1"
TUM = SHARED / "data" / "tum-fr1-rpy"
INTR = Intrinsics(640, 480, 500.0, 500.0, 320.0, 240.0)
_GL = np.diag([1.0, -1.0, -1.0, 1.0])
_BODY = np.eye(4)
_BODY[:3, :3] = [[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]


def written_as(name, T):
    """The pose a file of convention ``name`` holds for the true camera-to-world pose T."""
    if name == "inverted":
        return invert_pose(T)
    if name == "opengl":
        return T @ _GL
    if name == "x-forward":
        return T @ invert_pose(_BODY)
    if name == "w-first":  # written w x y z, read as x y z w
        x, y, z, w = Rotation.from_matrix(T[:3, :3]).as_quat()
        out = T.copy()
        out[:3, :3] = Rotation.from_quat([w, x, y, z]).as_matrix()
        return out
    return T


def test_agreement_of_a_wall_seen_from_two_places_by_hand():
    """A wall 2 m ahead of both cameras, the second 0.1 m to the right: a point moves 500 * 0.1 / 2
    = 25 px left, so of the sampled columns u = 4, 12, ..., 636 those from 28 on land in the image
    (77 of 80), each on the wall's 2 m. Turned a quarter about the vertical, the second camera
    sees none of it."""
    depth = np.full((480, 640), 2.0)
    T_b = np.eye(4)
    T_b[0, 3] = 0.1
    agree, inside = agreement(depth, depth, np.eye(4), T_b, INTR)
    assert agree == pytest.approx(77 / 80) and inside == pytest.approx(77 / 80)
    far = depth + 0.06  # the other frame's wall 6 cm further: beyond the 5 cm tolerance
    assert agreement(depth, far, np.eye(4), T_b, INTR) == (0.0, pytest.approx(77 / 80))
    turned = np.eye(4)
    turned[:3, :3] = Rotation.from_euler("y", 90, degrees=True).as_matrix()
    assert agreement(depth, depth, np.eye(4), turned, INTR) == (0.0, 0.0)
    assert agreement(np.zeros((480, 640)), depth, np.eye(4), T_b, INTR) == (0.0, 0.0)  # no readings


def _pairs(path, convention=None, n=4):
    rec = open_recording(path)
    starts = np.linspace(0, len(rec.frames) - 2, n).round().astype(int)
    out = []
    for i in starts:
        a, b = rec.frames[i].load(), rec.frames[i + 1].load()
        out.append((a.depth_m, b.depth_m, written_as(convention, a.T_world_camera),
                    written_as(convention, b.T_world_camera), a.intrinsics))
    return out


@pytest.mark.parametrize("convention", [None, *READINGS])
def test_each_convention_is_told_on_the_sample_recording(convention):
    verdict = judge_poses(_pairs(SAMPLE, convention))
    assert verdict.better == convention and not verdict.disagree
    # Read the right way, consecutive frames agree; the way the file was read, they do not.
    right = verdict.agree[convention or "as given"]
    assert right > 0.5 and all(v < right / 1.5 for k, v in verdict.agree.items() if k != (convention or "as given"))


@pytest.mark.skipif(not TUM.is_dir(), reason="../shared/data/tum-fr1-rpy absent")
@pytest.mark.parametrize("convention", [None, "inverted", "opengl", "w-first"])
def test_each_convention_is_told_on_a_real_recording(convention):
    """tum-fr1-rpy turns in place: consecutive views differ little, and still its own poses agree
    best (80 % of readings within 5 cm) and each wrong reading is named."""
    assert judge_poses(_pairs(TUM, convention, n=6)).better == convention


def test_no_pairs_no_verdict():
    assert judge_poses([]) is None


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    """The sample recording's first 8 frames as written, and written world-to-camera."""
    src = open_recording(SAMPLE)
    meta = yaml.safe_load((SAMPLE / "recording.yaml").read_text())
    out = {}
    for name in ("right", "inverted"):
        root = tmp_path_factory.mktemp(name)
        writer = RecordingWriter(root, meta)
        for i in range(8):
            f = src.frames[i].load()
            pose = written_as(None if name == "right" else name, f.T_world_camera)
            writer.write_frame(f.key, pose, f.rgb, np.round(f.depth_m * meta["depth"]["scale"]).astype(np.uint16))
            (root / "detections").mkdir(exist_ok=True)
            shutil.copy(SAMPLE / "detections" / f"{f.key}.json", root / "detections")
        writer.close()
        out[name] = root
    return out


def test_ingest_warns_once_and_the_reader_option_reads_them_right(recordings, tmp_path):
    r = CliRunner().invoke(cli, ["ingest", str(recordings["inverted"]), "--map", str(tmp_path / "bad.h5")])
    assert r.exit_code == 0, r.output
    warnings = [ln for ln in r.stderr.splitlines() if ln.startswith("warning:")]
    assert len(warnings) == 1 and "world-to-camera" in warnings[0]
    assert warnings[0].endswith("-r pose_convention=inverted")
    assert str(recordings["inverted"]) in warnings[0]
    for name, extra in (("fixed", ["-r", "pose_convention=inverted"]), ("right", [])):
        src = recordings["inverted" if name == "fixed" else "right"]
        r = CliRunner().invoke(cli, ["ingest", str(src), "--map", str(tmp_path / f"{name}.h5"), *extra])
        assert r.exit_code == 0 and "warning" not in r.stderr, r.output
    fixed, right = load_map(tmp_path / "fixed.h5"), load_map(tmp_path / "right.h5")
    assert fixed.objects.n == right.objects.n > 0
    for col in ("center", "size", "yaw", "status"):
        assert np.allclose(getattr(fixed.objects, col), getattr(right.objects, col), atol=1e-6), col
    # Read another way, the frames are other frames: their keys are not the file's as read plainly.
    recs = json.loads(fixed.sessions[0]["recordings"])
    assert recs == [open_recording(recordings["inverted"], options={"pose_convention": "inverted"}).identity]
    assert recs != [open_recording(recordings["inverted"]).identity]


def test_a_convention_given_where_the_poses_were_right_is_named(recordings, tmp_path):
    """Right poses read as world-to-camera: inverting them once more would fit, and the warning
    says to try without the option rather than to give it again."""
    r = CliRunner().invoke(cli, ["ingest", str(recordings["right"]), "--map", str(tmp_path / "m.h5"),
                                 "-r", "pose_convention=inverted"])
    warnings = [ln for ln in r.stderr.splitlines() if ln.startswith("warning:")]
    assert r.exit_code == 0 and len(warnings) == 1, r.output
    assert "read with -r pose_convention=inverted" in warnings[0] and "without -r pose_convention" in warnings[0]


def test_check_says_what_an_ingest_takes_and_writes_nothing(recordings):
    before = sorted(p.name for p in recordings["right"].rglob("*"))
    r = CliRunner().invoke(cli, ["check", str(recordings["right"])])
    assert r.exit_code == 0 and not r.stderr, r.output
    *table, summary = r.stdout.splitlines()
    assert summary == f"{recordings['right']}: ready to ingest"
    lines = dict(ln.split(None, 1) for ln in table)
    assert lines["camera"].startswith("320 x 240, fx 262.5 fy 262.5 cx 159.5 cy 119.5")
    assert lines["depth"].startswith("0.3-6 m") and lines["floor"].startswith("z = 0.00")
    assert lines["up"].startswith("z: map +z = the recording's (0.000, 0.000, 1.000)")
    assert lines["poses"].startswith(tuple(f"{p}% of depth readings within 5 cm" for p in range(50, 100)))
    doc = json.loads(CliRunner().invoke(cli, ["check", str(recordings["inverted"]), "--json"]).stdout)
    agree = doc["poses"]["agree"]
    assert doc["poses"]["better"] == "inverted" and agree["inverted"] > 0.5 > agree["as given"]
    assert len(doc["warnings"]) == 1 and doc["warnings"][0] == doc["poses"]["message"]
    assert doc["warnings"][0].endswith("-r pose_convention=inverted")
    r = CliRunner().invoke(cli, ["check", str(recordings["inverted"])])
    assert r.exit_code == 0 and r.stdout.splitlines()[-1] == f"{recordings['inverted']}: 1 warning (above)"
    assert r.stderr.startswith("warning: ") and len(r.stderr.splitlines()) == 1
    assert sorted(p.name for p in recordings["right"].rglob("*")) == before
    r = CliRunner().invoke(cli, ["check", str(recordings["right"] / "missing")])
    assert r.exit_code == 1 and "recording does not exist" in r.stderr and "Traceback" not in r.output


def test_an_unknown_convention_is_one_line(recordings, tmp_path):
    r = CliRunner().invoke(cli, ["ingest", str(recordings["right"]), "--map", str(tmp_path / "m.h5"),
                                 "-r", "pose_convention=sideways"])
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.exit_code == 1 and len(lines) == 1, r.output
    assert "pose_convention=sideways" in lines[0] and "inverted, opengl, x-forward, w-first" in lines[0]
    assert not (tmp_path / "m.h5").exists()


def test_the_frames_the_check_reads_are_handed_to_the_ingest():
    """Each partner frame is decoded once: the ingest's next load of it returns the frame the check
    read (the same depth array), and the load after that reads it anew."""
    from ltc_cli.ingest.pose_check import frame_pairs
    from ltc_cli.ingest.sampling import sample_frames_of

    rec = open_recording(SAMPLE)
    frames = sample_frames_of(rec, 6)  # positions 0, 15, 30, 45, 60, 75 of its 76
    pairs = frame_pairs(rec, frames, n=6)  # a pair for each, in the recording's order
    assert len(pairs) == 6
    positions = {f.key: k for k, f in enumerate(rec.frames)}
    for (_, depth_b, *_), a in zip(pairs, sorted(frames, key=lambda f: positions[f.key])):
        j = positions[a.key] + 1 if positions[a.key] + 1 < len(rec.frames) else positions[a.key] - 1
        first = rec.frames[j].load()
        assert first.depth_m is depth_b
        assert rec.frames[j].load().depth_m is not depth_b

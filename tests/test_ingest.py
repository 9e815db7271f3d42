"""End-to-end ingest: sessions, resume after SIGKILL, a second writer, and bad input."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from ltc_cli.cli import cli
from ltc_cli.map.model import ACTIVE
from ltc_cli.map.store import MapLock, load_map
from tests.recording import CLASSES, OBJECTS, write_recording

ROOT = Path(__file__).resolve().parent.parent


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args], catch_exceptions=False)


def active_objects(path):
    smap = load_map(path)
    t = smap.objects
    rows = np.flatnonzero(t.status == ACTIVE)
    return [(smap.classes[int(t.scores[r, :-1].argmax())], t.center[r], t.size[r]) for r in rows]


def snapshot(path):
    smap = load_map(path)
    return {k: v.copy() for k, v in smap.objects.columns().items()}, [e.kind for e in smap.events]


@pytest.fixture(scope="module")
def lap1(tmp_path_factory):
    return write_recording(tmp_path_factory.mktemp("lap1"))


def test_ingest_builds_one_object_per_real_object(lap1, tmp_path):
    m = tmp_path / "map.h5"
    r = run("ingest", lap1, "--map", m)
    assert r.exit_code == 0, r.output
    assert "5 frames ingested" in r.output
    objs = active_objects(m)
    assert sorted(c for c, _, _ in objs) == ["chair", "table", "tv"]
    for cls, center, size in objs:
        (x0, x1, y0, y1, z0, z1), k = next(o for o in OBJECTS if CLASSES[o[1]] == cls)
        # Seen from the front only: the y and z extents are observed, x is a face.
        assert center[1] == pytest.approx((y0 + y1) / 2, abs=0.05), cls
        assert center[2] == pytest.approx((z0 + z1) / 2, abs=0.05), cls
        assert np.sort(size)[-1] == pytest.approx(max(y1 - y0, z1 - z0), abs=0.08), cls
    # Ingesting the same recording again is a no-op: the file is not even rewritten.
    before = m.read_bytes()
    r = run("ingest", lap1, "--map", m)
    assert r.exit_code == 0 and "0 frames ingested" in r.output and "5 already in the map" in r.output
    assert m.read_bytes() == before


SWEEP = tuple(np.r_[np.linspace(1.5, -1.5, 9), np.linspace(-1.5, 1.5, 9)[1:]])


def test_two_laps_two_sessions_removes_the_absent_object(tmp_path):
    """The robot sweeps past the scene and back in each lap; the chair is gone in lap 2."""
    lap1 = write_recording(tmp_path / "lap1", cam_ys=SWEEP)
    lap2 = write_recording(tmp_path / "lap2", objects=[o for o in OBJECTS if CLASSES[o[1]] != "chair"], cam_ys=SWEEP)
    m = tmp_path / "map.h5"
    assert run("ingest", lap1, "--map", m).exit_code == 0
    r = run("ingest", lap2, "--map", m)
    assert r.exit_code == 0, r.output
    assert sorted(c for c, _, _ in active_objects(m)) == ["table", "tv"]
    smap = load_map(m)
    assert len(smap.sessions) == 2
    removed = [e for e in smap.events if e.kind == "removed"]
    assert len(removed) == 1 and removed[0].session == 1
    # With the static-world policy the chair stays (a ghost).
    m2 = tmp_path / "static.h5"
    run("ingest", lap1, "--map", m2, "--policy", "static")
    run("ingest", lap2, "--map", m2, "--policy", "static")
    assert sorted(c for c, _, _ in active_objects(m2)) == ["chair", "table", "tv"]
    r = run("info", m)
    assert r.exit_code == 0 and "2 sessions" in r.output.splitlines()[-1]
    # v_Other was learnt per class (the default): info says so instead of the 0.5 prior.
    assert r.output.count("v_other=learnt per class") == 2


def test_info_shows_the_up_axis_the_map_applied(tmp_path):
    from ltc_cli.map.store import save_map

    lap1 = write_recording(tmp_path / "lap1")
    m = tmp_path / "map.h5"
    assert run("ingest", lap1, "--map", m).exit_code == 0
    assert "map +z = the recording's (0.000, 0.000, 1.000), 0.0 deg from its +z" in run("info", m).output
    # A y-down world turned z-up: R_up maps the recording's -y onto +z (rotation about x by -90 deg).
    smap = load_map(m)
    smap.up_rotation = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])
    save_map(smap, m)
    assert "map +z = the recording's (0.000, -1.000, 0.000), 90.0 deg from its +z" in run("info", m).output


def test_an_up_axis_resting_on_the_cameras_alone_is_warned_about(tmp_path):
    """The test room shows a wall and box faces, no floor: with ``up: estimate`` the estimate can only
    be the cameras' mean up, and the ingest says so (once, naming the recording)."""
    rec = write_recording(tmp_path / "lap1")
    meta = yaml.safe_load((rec / "recording.yaml").read_text())
    (rec / "recording.yaml").write_text(yaml.safe_dump({**meta, "up": "estimate"}))
    r = run("ingest", rec, "--map", tmp_path / "m.h5")
    assert r.exit_code == 0
    assert r.output.count("no floor or table plane in the sampled frames") == 1
    assert f"{rec}: no floor" in r.output
    # ... and the cameras' guess is what it used (they look level in a z-up world): planes slicing
    # through the wall and the box faces 50-58 degrees off were not taken for a floor.
    np.testing.assert_allclose(load_map(tmp_path / "m.h5").up_rotation, np.eye(3), atol=1e-9)
    # Given (the default of this layout: z-up), nothing is estimated and nothing is said.
    r = run("ingest", write_recording(tmp_path / "lap2"), "--map", tmp_path / "m2.h5")
    assert r.exit_code == 0 and "no floor or table plane" not in r.output


def test_info_shows_a_fixed_v_other_when_nothing_is_learnt(tmp_path):
    lap1 = write_recording(tmp_path / "lap1")
    m = tmp_path / "map.h5"
    assert run("ingest", lap1, "--map", m, "--set", "maintenance.learn_detection_rate=false",
               "--set", "maintenance.v_other=0.7").exit_code == 0
    r = run("info", m)
    assert r.exit_code == 0 and "v_other=0.7 " in r.output and "learnt" not in r.output


def ltc_process(*args, env_extra=None):
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
    env.update(env_extra or {})
    return subprocess.Popen([sys.executable, "-m", "ltc_cli.cli", *map(str, args)], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def wait_for_file(path, proc, timeout=60):
    """Poll until ``proc`` creates ``path`` (its ready signal); fail if it ends or times out first."""
    deadline = time.monotonic() + timeout
    while not path.exists():
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "no ready signal"
        time.sleep(0.01)


def frames_in(path):
    try:
        return len(load_map(path).frame_keys)
    except Exception:
        return 0


@pytest.mark.slow
def test_sigkill_part_way_then_resume_gives_the_same_map(tmp_path):
    rec = write_recording(tmp_path / "rec", cam_ys=tuple(np.linspace(1.5, -1.5, 16)))
    ref = tmp_path / "ref.h5"
    assert run("ingest", rec, "--map", ref).exit_code == 0
    m = tmp_path / "map.h5"
    env = {"LTC_PLUGINS": "tests.slow_detector", "LTC_TEST_DELAY": "0.15"}
    p = ltc_process("ingest", rec, "--map", m, "--detector", "slow-recorded", "--checkpoint-every", "2", env_extra=env)
    deadline = time.time() + 60
    while frames_in(m) < 4 and time.time() < deadline and p.poll() is None:
        time.sleep(0.02)
    assert p.poll() is None, "the ingest ended before it could be killed"
    p.send_signal(signal.SIGKILL)
    p.wait()
    done = frames_in(m)
    assert 4 <= done < 16  # the map opens, with the frames of the last checkpoint
    assert not list(tmp_path.glob(".map.h5.tmp*")) or True  # a killed writer may leave its temp file
    p = ltc_process("ingest", rec, "--map", m, "--detector", "slow-recorded", env_extra={**env, "LTC_TEST_DELAY": "0"})
    out, err = p.communicate(timeout=120)
    assert p.returncode == 0, err
    assert f"{16 - done} frames ingested" in out and f"{done} already in the map" in out
    a, ev_a = snapshot(ref)
    b, ev_b = snapshot(m)
    assert ev_a == ev_b
    for k in a:
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)
    assert len(load_map(m).sessions) == 1  # the interrupted session was resumed, not duplicated


@pytest.mark.slow
def test_sigterm_commits_and_exits(tmp_path):
    rec = write_recording(tmp_path / "rec", cam_ys=tuple(np.linspace(1.5, -1.5, 12)))
    m = tmp_path / "map.h5"
    ready = tmp_path / "ready"
    env = {"LTC_PLUGINS": "tests.slow_detector", "LTC_TEST_DELAY": "0.2", "LTC_TEST_READY": str(ready)}
    p = ltc_process("ingest", rec, "--map", m, "--detector", "slow-recorded", "--checkpoint-every", "0", env_extra=env)
    wait_for_file(ready, p)  # the first frame is being detected: the handlers are in place
    p.send_signal(signal.SIGTERM)
    out, err = p.communicate(timeout=60)
    assert p.returncode == 143, err
    assert "interrupted" in out
    assert 0 < frames_in(m) < 12  # committed on the signal although no checkpoint was due


def test_second_concurrent_writer_gets_a_clear_error(lap1, tmp_path):
    m = tmp_path / "map.h5"
    with MapLock(m):
        r = CliRunner().invoke(cli, ["ingest", str(lap1), "--map", str(m)])
    assert r.exit_code == 1
    assert "another ltc process" in r.output and str(m) in r.output
    assert not m.exists()


# -- bad input -------------------------------------------------------------------------------

def _png16(path, shape, value=2000):
    from PIL import Image

    Image.fromarray(np.full(shape, value, np.uint16)).save(path)


def corrupt_missing_rgb(rec):
    os.remove(rec / "rgb" / "000000.png")
    return rec / "rgb" / "000000.png"


def corrupt_unreadable_rgb(rec):
    (rec / "rgb" / "000000.png").write_bytes(b"\x89PNG but not really")
    return rec / "rgb" / "000000.png"


def corrupt_depth_size(rec):
    _png16(rec / "depth" / "000000.png", (240, 320))
    return rec / "depth" / "000000.png"


def corrupt_depth_type(rec):
    from PIL import Image

    Image.fromarray(np.full((480, 640), 20, np.uint8)).save(rec / "depth" / "000000.png")
    return rec / "depth" / "000000.png"


def _pose_line(rec, new):
    p = rec / "poses.txt"
    p.write_text(new + "\n")
    return p


def corrupt_missing_pose(rec):
    return _pose_line(rec, "# no poses for 000000")


def corrupt_nonfinite_pose(rec):
    return _pose_line(rec, "000000 0 nan 1 0 0 0 1")


def corrupt_not_rotation(rec):
    return _pose_line(rec, "000000 0 0 1 0.5 0.5 0.5 1.5")


BAD_FRAMES = [corrupt_missing_rgb, corrupt_unreadable_rgb, corrupt_depth_size, corrupt_depth_type,
              corrupt_missing_pose, corrupt_nonfinite_pose, corrupt_not_rotation]


@pytest.mark.parametrize("corrupt", BAD_FRAMES, ids=lambda f: f.__name__[8:])
def test_bad_frame_gives_one_clear_line_and_never_changes_the_map(lap1, tmp_path, corrupt):
    m = tmp_path / "map.h5"
    assert run("ingest", lap1, "--map", m).exit_code == 0
    before = m.read_bytes()
    bad = write_recording(tmp_path / "bad", cam_ys=(0.0,))
    culprit = corrupt(bad)
    for strict in (False, True):
        args = ["ingest", str(bad), "--map", str(m)] + (["--strict"] if strict else [])
        r = CliRunner().invoke(cli, args)
        lines = [ln for ln in r.stderr.splitlines() if ln.strip()] if hasattr(r, "stderr") else []
        if strict:
            assert r.exit_code == 1
            assert len(lines) == 1 and str(culprit) in lines[0] and "Traceback" not in r.output
        else:
            # Its only frame was bad, so the run mapped nothing: the warning, then one error line.
            assert r.exit_code == 1
            assert len(lines) == 2 and lines[0].startswith("warning: skipped frame 000000") and str(culprit) in lines[0]
            assert "no frame could be mapped" in lines[1] and str(bad) in lines[1]
            assert "1 skipped" in r.stdout
        assert m.read_bytes() == before


def test_a_run_whose_every_frame_is_bad_fails_with_one_line(tmp_path):
    """Camera 320x240 in recording.yaml, images 640x480: each of the 5 frames is skipped, nothing is
    mapped, and that is an error (exit 1, one line after the warnings), the summary still printed."""
    rec = write_recording(tmp_path / "rec")
    meta = yaml.safe_load((rec / "recording.yaml").read_text())
    meta["camera"].update(width=320, height=240)
    (rec / "recording.yaml").write_text(yaml.safe_dump(meta))
    m = tmp_path / "map.h5"
    r = CliRunner().invoke(cli, ["ingest", str(rec), "--map", str(m)])
    assert r.exit_code == 1
    assert "0 frames ingested, 5 skipped (5 depth image is 640x480, the camera is 320x240), 0 already in the map" \
        in r.stdout
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 6 and all(ln.startswith("warning: skipped frame") for ln in lines[:5])
    assert lines[5] == f"Error: {rec}: no frame could be mapped, all 5 were bad (see the warnings); {m} is unchanged"
    assert not m.exists()


def test_many_frames_skipped_for_one_reason_are_listed_ten_times_then_counted(tmp_path):
    """A recording copied in part: 12 of 14 frames lack their depth image, one colour image is
    unreadable. The first 10 missing ones get a line each, the 11th says that the rest are only
    counted, the 12th gets none; the unreadable one (another reason) still gets its line, and the
    summary counts both reasons."""
    rec = write_recording(tmp_path / "rec", cam_ys=tuple(np.linspace(-1.5, 1.5, 14)))
    for i in range(12):
        os.remove(rec / "depth" / f"{i:06d}.png")
    (rec / "rgb" / "000012.png").write_bytes(b"\x89PNG but not really")
    m = tmp_path / "map.h5"
    r = CliRunner().invoke(cli, ["ingest", str(rec), "--map", str(m)])
    assert r.exit_code == 0, r.output
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 12, lines
    for i in range(10):
        assert lines[i] == f"warning: skipped frame {i:06d}: {rec / 'depth' / f'{i:06d}.png'}: image file is missing"
    assert lines[10] == (f"warning: skipped frame 000010: {rec / 'depth' / '000010.png'}: image file is missing; "
                         'further frames skipped for "image file is missing" are counted in the summary, not listed')
    assert lines[11].startswith(f"warning: skipped frame 000012: {rec / 'rgb' / '000012.png'}: cannot read image (")
    assert "1 frame ingested, 13 skipped (12 image file is missing, 1 cannot read image), 0 already" in r.stdout


@pytest.mark.parametrize("text", ["format: ltc-recording/1\ncamera: [1, 2\n", "format: ltc-recording/1\ncamera: {width: 640}\ndepth: {scale: 1000}\n", "just a string\n"])
def test_malformed_recording_yaml(lap1, tmp_path, text):
    m = tmp_path / "map.h5"
    assert run("ingest", lap1, "--map", m).exit_code == 0
    before = m.read_bytes()
    bad = write_recording(tmp_path / "bad", cam_ys=(0.0,))
    (bad / "recording.yaml").write_text(text)
    r = CliRunner().invoke(cli, ["ingest", str(bad), "--map", str(m)])
    assert r.exit_code == 1
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and str(bad / "recording.yaml") in lines[0], r.stderr
    assert m.read_bytes() == before


def test_refuses_a_file_that_is_not_a_map(lap1, tmp_path):
    m = tmp_path / "notes.h5"
    m.write_text("my notes")
    r = CliRunner().invoke(cli, ["ingest", str(lap1), "--map", str(m)])
    assert r.exit_code == 1 and "not an ltc map" in r.stderr
    assert m.read_text() == "my notes"


def test_unknown_setting_and_plugin_are_one_line_errors(lap1, tmp_path):
    r = CliRunner().invoke(cli, ["ingest", str(lap1), "--map", str(tmp_path / "m.h5"), "--set", "modeling.epsilon=3"])
    assert r.exit_code == 1 and "unknown setting 'modeling.epsilon'" in r.stderr
    r = CliRunner().invoke(cli, ["ingest", str(lap1), "--map", str(tmp_path / "m.h5"), "--metric", "nope"])
    assert r.exit_code == 1 and "unknown metric 'nope'" in r.stderr

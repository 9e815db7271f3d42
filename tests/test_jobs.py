"""ltc ingest --jobs N: detection runs ahead in threads, and the map is exactly the sequential one."""

import shutil
import threading
import time

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

import ltc_cli.recordings.writer as rec_writer
import ltc_cli.tools.simulate as sim
from ltc_cli import hookimpl, plugins
from ltc_cli.cli import cli
from ltc_cli.config import defaults
from ltc_cli.errors import ConfigError
from ltc_cli.ingest.session import ingest
from ltc_cli.map.store import load_map
from ltc_plugins.recorded import RecordedDetector


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


@pytest.fixture(scope="module")
def laps(tmp_path_factory):
    out = tmp_path_factory.mktemp("house")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(rec_writer, "PNG_LEVEL", 1)  # fast PNGs: same pixels
        sim.simulate(out, scene="tiny", laps=2, seed=2, width=320, height=240, frames_per_room=20)
    return out / "lap1", out / "lap2"


def state(path):
    """Everything a map holds but wall-clock times: object columns, events, frame keys, sessions."""
    smap = load_map(path)
    cols = {k: v.copy() for k, v in smap.objects.columns().items()}
    events = [(e.session, e.frame, e.frame_key, e.kind, e.object_id, e.other_id, e.detail) for e in smap.events]
    sessions = [{k: v for k, v in s.items() if k not in ("started", "finished")} for s in smap.sessions]
    return cols, events, sorted(smap.frame_keys), sessions


def assert_same_map(a, b):
    ca, ea, ka, sa = state(a)
    cb, eb, kb, sb = state(b)
    assert ca.keys() == cb.keys()
    for k in ca:
        np.testing.assert_array_equal(ca[k], cb[k], err_msg=k)
    assert ea == eb
    assert ka == kb
    assert sa == sb


def summary_line(output):
    line = output.strip().splitlines()[-1]
    return line.rsplit(";", 1)[0]  # without the seconds


def test_jobs_2_makes_exactly_the_map_of_jobs_1(laps, tmp_path):
    lap1, lap2 = laps
    maps = {}
    for jobs in (1, 2):
        m = maps[jobs] = tmp_path / f"j{jobs}.h5"
        outs = []
        for lap in (lap1, lap2):
            r = run("ingest", lap, "--map", m, "--jobs", jobs, "--checkpoint-every", 3)
            assert r.exit_code == 0, r.output
            outs.append(summary_line(r.stdout).replace(str(m), "MAP"))
        maps[jobs] = (m, outs)
    assert maps[1][1] == maps[2][1]
    assert "20 frames ingested" in maps[1][1][0]
    smap = load_map(maps[1][0])
    assert any(e.kind == "non-detection" for e in smap.events) and len(smap.sessions) == 2
    assert_same_map(maps[1][0], maps[2][0])


def corrupt_copy(lap, dest, bad=("000007", "000012")):
    """A copy of lap whose frames ``bad`` cannot be read: a depth image of the wrong size, a
    missing colour image."""
    shutil.copytree(lap, dest)
    Image.fromarray(np.zeros((10, 10), np.uint16)).save(dest / "depth" / f"{bad[0]}.png")
    (dest / "rgb" / f"{bad[1]}.png").unlink()
    return dest


def test_bad_frames_are_skipped_the_same_way(laps, tmp_path):
    bad = corrupt_copy(laps[0], tmp_path / "bad")
    res = {}
    for jobs in (1, 2):
        m = tmp_path / f"j{jobs}.h5"
        r = run("ingest", bad, "--map", m, "--jobs", jobs)
        assert r.exit_code == 0, r.output
        assert "18 frames ingested, 2 skipped" in r.stdout
        warnings = [ln for ln in r.stderr.splitlines() if ln.strip()]
        assert len(warnings) == 2 and warnings[0].startswith("warning: skipped frame 000007")
        assert warnings[1].startswith("warning: skipped frame 000012")
        res[jobs] = (m, warnings)
    assert res[1][1] == res[2][1]
    assert_same_map(res[1][0], res[2][0])
    # --strict stops at the first bad frame, with the frames before it committed, in both modes.
    for jobs in (1, 2):
        m = tmp_path / f"strict{jobs}.h5"
        r = run("ingest", bad, "--map", m, "--jobs", jobs, "--strict")
        lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
        assert r.exit_code == 1 and len(lines) == 1 and str(bad / "depth" / "000007.png") in lines[0], r.stderr
        assert len(load_map(m).frame_keys) == 7
    assert_same_map(tmp_path / "strict1.h5", tmp_path / "strict2.h5")


def test_stop_part_way_then_resume_gives_the_same_map(laps, tmp_path):
    lap1 = laps[0]
    ref = tmp_path / "ref.h5"
    ingest([lap1], ref, defaults())
    m = tmp_path / "m.h5"
    done = []
    s = ingest([lap1], m, defaults(), jobs=2, checkpoint_every=4, on_frame=lambda summ: done.append(1),
               should_stop=lambda: len(done) >= 9)
    assert s.interrupted and s.frames_done == 9
    assert len(load_map(m).frame_keys) == 9  # the look-ahead's frames were dropped, not mapped
    s = ingest([lap1], m, defaults(), jobs=3)
    assert not s.interrupted and s.frames_done == 11 and s.frames_already == 9
    assert_same_map(ref, m)


def test_frames_already_in_the_map_are_not_loaded(laps, tmp_path):
    rec = tmp_path / "rec"
    shutil.copytree(laps[0], rec)
    m = tmp_path / "m.h5"
    assert run("ingest", rec, "--map", m).exit_code == 0
    before = m.read_bytes()
    for p in (rec / "rgb").iterdir():  # loading any frame now fails (the identity does not change)
        p.unlink()
    r = run("ingest", rec, "--map", m, "--jobs", 2)
    assert r.exit_code == 0 and "0 frames ingested, 0 skipped, 20 already in the map" in r.stdout
    assert not r.stderr.strip()
    assert m.read_bytes() == before


class Probe(RecordedDetector):
    """The recorded detector, slowed down, counting how many threads are in ``detect`` at once;
    it declares itself not thread-safe (as a third-party detector that says nothing is taken)."""

    thread_safe = False
    active = 0
    peak = 0
    lock = threading.Lock()

    def detect(self, frame):
        cls = type(self)
        with cls.lock:
            cls.active += 1
            cls.peak = max(cls.peak, cls.active)
        try:
            time.sleep(0.02)
            return super().detect(frame)
        finally:
            with cls.lock:
                cls.active -= 1


class SafeProbe(Probe):
    thread_safe = True


class ProbePlugin:
    @hookimpl
    def register_detectors(self, register):
        register("probe", Probe.from_options)
        register("safe-probe", SafeProbe.from_options)


@pytest.fixture
def probes():
    plugins.register_plugin(ProbePlugin(), name="test-probes")
    yield
    plugins.unregister_plugin("test-probes")


def test_detect_runs_concurrently_only_for_thread_safe_detectors(laps, tmp_path, probes):
    ref = tmp_path / "ref.h5"
    ingest([laps[0]], ref, defaults())
    for name, cls, peak in (("probe", Probe, 1), ("safe-probe", SafeProbe, 2)):
        cfg = defaults()
        cfg["detector"]["name"] = name
        cls.peak = 0
        m = tmp_path / f"{name}.h5"
        s = ingest([laps[0]], m, cfg, jobs=2)
        assert s.frames_done == 20
        assert cls.peak == peak, name
        smap, rmap = load_map(m), load_map(ref)
        for k, v in rmap.objects.columns().items():
            np.testing.assert_array_equal(v, smap.objects.columns()[k], err_msg=k)


def test_jobs_must_be_positive(laps, tmp_path):
    with pytest.raises(ConfigError):
        ingest([laps[0]], tmp_path / "m.h5", defaults(), jobs=0)
    r = run("ingest", laps[0], "--map", tmp_path / "m.h5", "--jobs", 0)
    assert r.exit_code == 2 and not (tmp_path / "m.h5").exists()

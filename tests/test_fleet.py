"""Distributed ingest on Dask (ltc ingest --dask, ltc ingest-many): stage 1 on the workers, stages
2-4 on the writer, and the maps exactly those of single-process ingests."""

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import ltc_cli.ingest.frame_setup as frame_setup
import ltc_cli.ingest.remote as remote
import ltc_cli.ingest.session as session_module
import ltc_cli.recordings.writer as rec_writer
import ltc_cli.tools.simulate as sim
from ltc_cli import plugins
from ltc_cli.config import defaults
from ltc_cli.errors import LtcError
from ltc_cli.ingest.cluster import Cluster, DaskError, open_cluster
from ltc_cli.ingest.fleet import ingest_many, summary_table
from ltc_cli.ingest.remote import depth_pixels, pack_depth, unpack_depth
from ltc_cli.ingest.session import ingest
from ltc_cli.map.store import load_map
from ltc_cli.pipeline.visibility import ray_grid
from ltc_cli.types import Intrinsics
from tests.test_ingest import wait_for_file
from tests.test_jobs import assert_same_map, corrupt_copy, run, summary_line
from tests.test_still_frames import COPIES, N_FRAMES, poses_unknown, with_still_copies

distributed = pytest.importorskip("distributed")


@pytest.fixture(scope="module")
def laps(tmp_path_factory):
    """Three laps of the tiny simulated house, 20 frames each, at 320 x 240."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(rec_writer, "PNG_LEVEL", 1)  # fast PNGs: same pixels
        out = tmp_path_factory.mktemp("house")
        sim.simulate(out, scene="tiny", laps=3, seed=2, width=320, height=240, frames_per_room=20)
    return tuple(out / f"lap{k}" for k in (1, 2, 3))


@pytest.fixture(scope="module")
def cluster():
    """Two single-thread workers in this process (threads, not processes: quick to start)."""
    local = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=":0")
    with Cluster(distributed.Client(local), local) as c:
        yield c


# -- what travels ------------------------------------------------------------------------------

def test_depth_travels_as_the_pixels_stage_4_reads():
    intr = Intrinsics(64, 48, 50.0, 50.0, 31.5, 23.5)
    depth = np.random.default_rng(0).uniform(0.5, 4.0, (48, 64)).astype(np.float32)
    rows, cols = depth_pixels(intr, 8)
    # ray_grid's pixel centres (3.5, 11.5, ...) read the pixels at 3, 11, ...: by hand.
    np.testing.assert_array_equal(rows, [3, 11, 19, 27, 35, 43])
    np.testing.assert_array_equal(cols, [3, 11, 19, 27, 35, 43, 51, 59])
    samples = pack_depth(depth, intr, 8)
    assert samples.shape == (6, 8) and samples.dtype == np.float32
    back = unpack_depth(samples, depth.shape, intr, 8)
    u, v = ray_grid(intr, 8)
    np.testing.assert_array_equal(back[v.astype(int), u.astype(int)], depth[v.astype(int), u.astype(int)])
    assert np.count_nonzero(back) == 48  # nothing else travels


# -- ltc ingest --dask ---------------------------------------------------------------------------

def test_dask_map_equals_the_single_process_map(laps, tmp_path, cluster):
    ref, m = tmp_path / "ref.h5", tmp_path / "dask.h5"
    for lap in laps[:2]:
        a = ingest([lap], ref, defaults(), checkpoint_every=3)
        b = ingest([lap], m, defaults(), checkpoint_every=3, cluster=cluster)
        for k in ("frames_done", "detections", "created", "merged", "removed", "non_detections", "objects"):
            assert getattr(a, k) == getattr(b, k), k
    assert a.frames_done == 20 and a.removed + a.non_detections > 0  # the second lap maintained the map
    assert_same_map(ref, m)


@pytest.mark.parametrize("poses_known", [True, False])
def test_still_frames_on_dask_make_the_single_process_map(tmp_path, cluster, monkeypatch, poses_known):
    """The writer judges a still camera's frames by the poses the reader knows before loading, and
    never sends them to the workers; a reader that does not know them (a plugin's) has them
    modeled there, and the writer leaves them out. Either way the map is a single process's."""
    rec = with_still_copies(tmp_path)
    a = ingest([rec], tmp_path / "one.h5", defaults())
    if not poses_known:
        monkeypatch.setattr(session_module, "open_recording", poses_unknown(session_module.open_recording))
    modeled, real = [], remote.model_frame
    monkeypatch.setattr(remote, "model_frame", lambda *args: modeled.append(1) or real(*args))
    b = ingest([rec], tmp_path / "dask.h5", defaults(), cluster=cluster)
    assert len(modeled) == N_FRAMES + (0 if poses_known else COPIES)
    assert (a.frames_done, a.frames_still) == (b.frames_done, b.frames_still) == (N_FRAMES, COPIES)
    assert_same_map(tmp_path / "one.h5", tmp_path / "dask.h5")


def test_a_range_of_frames_on_dask_makes_the_single_process_map(laps, tmp_path, cluster):
    """--frames on Dask: the workers open the whole recording and take the writer's positions in
    the range, so they must cut it as the writer did (every other frame from the third: a position
    k of the range is frame 2 + 2k)."""
    frames = slice(2, None, 2)
    ingest([laps[0]], tmp_path / "one.h5", defaults(), frames=frames)
    s = ingest([laps[0]], tmp_path / "dask.h5", defaults(), frames=frames, cluster=cluster)
    assert s.frames_done + s.frames_still + s.frames_skipped == 9  # frames 2, 4, ..., 18 of 20
    assert_same_map(tmp_path / "one.h5", tmp_path / "dask.h5")


@pytest.mark.parametrize("batch", [1, 3])  # 3 does not divide 20: the last task is short
def test_any_batch_size_makes_the_same_map(laps, tmp_path, cluster, batch):
    ref, m = tmp_path / "ref.h5", tmp_path / "dask.h5"
    ingest([laps[0]], ref, defaults())
    ingest([laps[0]], m, defaults(), cluster=Cluster(cluster.client, batch=batch))
    assert_same_map(ref, m)


def test_workers_model_with_the_depth_error_the_writer_measured(laps, tmp_path, cluster, monkeypatch):
    monkeypatch.setattr(frame_setup, "estimate_depth_noise", lambda images: (0.0321, 99))
    seen, real = [], remote.model_frame

    def spy(*args):
        seen.append(args[9])  # measured_noise (the workers are threads of this process)
        return real(*args)

    monkeypatch.setattr(remote, "model_frame", spy)
    ingest([laps[0]], tmp_path / "m.h5", defaults(), cluster=cluster)
    assert len(seen) == 20 and set(seen) == {0.0321}


def test_stop_part_way_then_resume_on_dask_gives_the_same_map(laps, tmp_path, cluster):
    ref, m = tmp_path / "ref.h5", tmp_path / "m.h5"
    ingest([laps[0]], ref, defaults())
    done = []
    s = ingest([laps[0]], m, defaults(), cluster=cluster, checkpoint_every=4, on_frame=lambda summ: done.append(1),
               should_stop=lambda: len(done) >= 9)
    assert s.interrupted and s.frames_done == 9
    assert len(load_map(m).frame_keys) == 9  # the frames still in flight were dropped, not mapped
    s = ingest([laps[0]], m, defaults(), cluster=cluster)
    assert not s.interrupted and s.frames_done == 11 and s.frames_already == 9
    assert_same_map(ref, m)


def test_a_stop_request_ends_the_wait_for_a_cluster_that_has_no_worker(laps, tmp_path):
    asked = []

    def should_stop():  # no at the first frame; yes once the writer waits for its result
        asked.append(1)
        return len(asked) > 1

    local = distributed.LocalCluster(n_workers=0, processes=False, dashboard_address=":0")
    with Cluster(distributed.Client(local), local) as c:
        s = ingest([laps[0]], tmp_path / "m.h5", defaults(), cluster=c, should_stop=should_stop)
    assert s.interrupted and s.frames_done == 0
    assert not (tmp_path / "m.h5").exists()  # nothing mapped: the file is not created


def test_bad_frames_on_workers_are_skipped_at_their_turn(laps, tmp_path, cluster):
    bad = corrupt_copy(laps[0], tmp_path / "bad")
    warned = {}
    for name, c in (("local", None), ("dask", cluster)):
        msgs = warned[name] = []
        s = ingest([bad], tmp_path / f"{name}.h5", defaults(), cluster=c, warn=msgs.append)
        assert s.frames_done == 18 and s.frames_skipped == 2
    assert warned["local"] == warned["dask"] and warned["dask"][0].startswith("skipped frame 000007")
    assert_same_map(tmp_path / "local.h5", tmp_path / "dask.h5")
    with pytest.raises(LtcError) as err:  # --strict stops there, with the frames before it committed
        ingest([bad], tmp_path / "strict.h5", defaults(), cluster=cluster, strict=True)
    assert str(bad / "depth" / "000007.png") in str(err.value)
    assert len(load_map(tmp_path / "strict.h5").frame_keys) == 7


def test_cli_dask_local_starts_workers_and_makes_the_same_map(laps, tmp_path):
    ref, m = tmp_path / "ref.h5", tmp_path / "m.h5"
    a = run("ingest", laps[0], "--map", ref)
    b = run("ingest", laps[0], "--map", m, "--dask", "local:2")
    assert a.exit_code == 0 and b.exit_code == 0, b.output
    assert summary_line(a.stdout).replace(str(ref), "MAP") == summary_line(b.stdout).replace(str(m), "MAP")
    assert_same_map(ref, m)


def test_a_worker_killed_mid_run_does_not_change_the_map(laps, tmp_path, monkeypatch):
    cfg = defaults()
    cfg["detector"]["name"] = "gate-recorded"
    monkeypatch.setenv("LTC_PLUGINS", "tests.gate_detector")
    plugins.reset()
    try:
        ref = tmp_path / "ref.h5"
        ingest([laps[0]], ref, cfg)  # the gate is not armed yet: the plain recorded detections
        gate = tmp_path / "gate"
        gate.mkdir()
        monkeypatch.setenv("LTC_TEST_GATE", str(gate))
        monkeypatch.setenv("LTC_TEST_GATE_FRAME", "000010")
        local = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0")
        with Cluster(distributed.Client(local), local) as c:
            killed = {}

            def kill_when_ready():  # the worker holding frame 10 says so, then dies
                deadline = time.monotonic() + 120
                while not (gate / "ready").exists() and time.monotonic() < deadline:
                    time.sleep(0.01)
                killed["pid"] = int((gate / "ready").read_text())
                os.kill(killed["pid"], signal.SIGKILL)

            killer = threading.Thread(target=kill_when_ready)
            killer.start()
            m = tmp_path / "m.h5"
            s = ingest([laps[0]], m, cfg, cluster=c, checkpoint_every=4)
            killer.join()
            assert killed["pid"] not in c.client.run(os.getpid).values()  # that worker is gone
        assert s.frames_done == 20 and s.frames_skipped == 0
        assert_same_map(ref, m)  # no frame lost, none mapped twice, same order
    finally:
        monkeypatch.delenv("LTC_PLUGINS")
        plugins.reset()


def ltc_job(*args, env):
    """``ltc ARGS`` in a process group of its own, as a terminal runs a job."""
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parent.parent), **env}
    return subprocess.Popen([sys.executable, "-m", "ltc_cli.cli", *map(str, args)], env=env, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True)


def test_ctrl_c_at_the_terminal_stops_the_writer_not_the_local_workers(laps, tmp_path):
    """SIGINT to the whole process group, as a terminal sends it: the writer commits and exits 130,
    the local workers (which ignore it) are closed by the writer, and the same command resumes."""
    ref, m, ready = tmp_path / "ref.h5", tmp_path / "m.h5", tmp_path / "ready"
    env = {"LTC_PLUGINS": "tests.slow_detector", "LTC_TEST_DELAY": "0.1", "LTC_TEST_READY": str(ready)}
    args = ("ingest", laps[0], "--map", m, "--detector", "slow-recorded", "--dask", "local:2", "--dask-batch", "1")
    p = ltc_job(*args, "--checkpoint-every", "2", env=env)
    wait_for_file(ready, p)  # a worker is detecting: the cluster is up, the handlers are in place
    os.killpg(p.pid, signal.SIGINT)
    out, err = p.communicate(timeout=120)
    assert p.returncode == 130, err
    assert "(interrupted: run the same command again to resume)" in out
    assert "Traceback" not in err and "KeyboardInterrupt" not in err
    done = len(load_map(m).frame_keys) if m.exists() else 0
    p = ltc_job(*args, env={**env, "LTC_TEST_DELAY": "0"})
    out, err = p.communicate(timeout=120)
    assert p.returncode == 0 and f"{20 - done} frames ingested" in out, err
    p = ltc_job("ingest", laps[0], "--map", ref, "--detector", "slow-recorded", env={**env, "LTC_TEST_DELAY": "0"})
    assert p.communicate(timeout=120) and p.returncode == 0
    assert_same_map(ref, m)


def test_without_dask_the_option_says_what_to_install(laps, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # as if ltc[dask] were not installed
    r = run("ingest", laps[0], "--map", tmp_path / "m.h5", "--dask", "local")
    assert r.exit_code == 1
    assert r.stderr.strip() == "Error: --dask needs the optional extra ltc[dask]: pip install 'ltc[dask]'"
    assert not (tmp_path / "m.h5").exists()


def test_bad_dask_options_are_one_line(laps, tmp_path):
    r = run("ingest", laps[0], "--map", tmp_path / "m.h5", "--dask", "local", "--jobs", "2")
    assert r.exit_code == 2 and "--jobs and --dask" in r.stderr
    r = run("ingest", laps[0], "--map", tmp_path / "m.h5", "--dask", "local:0")
    assert r.exit_code == 1 and len(r.stderr.strip().splitlines()) == 1 and "local:N" in r.stderr
    with pytest.raises(DaskError, match="cannot reach the Dask scheduler at tcp://127.0.0.1:9"):
        open_cluster("tcp://127.0.0.1:9", timeout=0.5)  # the discard port: nothing listens
    assert not (tmp_path / "m.h5").exists()


# -- ltc ingest-many -----------------------------------------------------------------------------

def write_manifest(path, text):
    path.write_text(text)
    return path


def test_manifest_into_two_maps_equals_sequential_ingests(laps, tmp_path, cluster):
    lap1, lap2, lap3 = laps
    # Site A's recordings are listed out of time order; they go in by time.
    manifest = write_manifest(tmp_path / "fleet.yaml", f"""\
format: ltc-manifest/1
maps:
  - name: site-a
    map: maps/a.h5
    recordings:
      - {{path: {lap2}, time: 2024-05-02T09:00:00Z}}
      - {{path: {lap1}, time: 2024-05-01T09:00:00Z}}
  - name: site-b
    map: maps/b.h5
    recordings: [{lap3}]
""")
    (tmp_path / "maps").mkdir()
    rows = ingest_many(manifest, cluster=cluster, writers=2)
    assert [(r.map_name, r.recording, r.status) for r in rows] == [
        ("site-a", str(lap1), "ok"), ("site-a", str(lap2), "ok"), ("site-b", str(lap3), "ok")]
    seq = tmp_path / "seq"
    seq.mkdir()
    for lap, name in ((lap1, "a.h5"), (lap2, "a.h5"), (lap3, "b.h5")):
        ingest([lap], seq / name, defaults())
    assert_same_map(seq / "a.h5", tmp_path / "maps" / "a.h5")
    assert_same_map(seq / "b.h5", tmp_path / "maps" / "b.h5")
    assert len(load_map(tmp_path / "maps" / "a.h5").sessions) == 2


def test_a_manifest_gives_reader_options_and_frame_ranges(laps, tmp_path):
    """A recording entry's ``options`` are ltc ingest's -r, its ``frames`` --frames: one folder
    listed once per range makes the sessions those ingests make (pose_convention chosen because a
    map read with it differs from one read without)."""
    lap1 = laps[0]
    manifest = write_manifest(tmp_path / "fleet.yaml", f"""\
format: ltc-manifest/1
maps:
  - map: m.h5
    recordings:
      - {{path: {lap1}, frames: "0:12", options: {{pose_convention: inverted}}}}
      - {{path: {lap1}, frames: "12:", options: {{pose_convention: inverted}}}}
""")
    rows = ingest_many(manifest, writers=1)
    assert [r.status for r in rows] == ["ok", "ok"], [r.error for r in rows]
    table = summary_table(rows)
    assert " [0:12] " in table[1] and " [12:] " in table[2]
    seq = tmp_path / "seq.h5"
    for frames in (slice(0, 12), slice(12, None)):
        ingest([lap1], seq, defaults(), reader_options={"pose_convention": "inverted"}, frames=frames)
    assert_same_map(seq, tmp_path / "m.h5")
    assert [s["frames"] for s in load_map(tmp_path / "m.h5").sessions] == ["0:12", "12:"]
    read_so, plain = tmp_path / "inverted.h5", tmp_path / "plain.h5"
    ingest([lap1], read_so, defaults(), reader_options={"pose_convention": "inverted"}, frames=slice(0, 12))
    ingest([lap1], plain, defaults(), frames=slice(0, 12))
    a, b = load_map(read_so).objects.center, load_map(plain).objects.center
    assert a.shape != b.shape or not np.allclose(a, b)  # the option changes the map
    bad = write_manifest(tmp_path / "bad.yaml",
                         f"format: ltc-manifest/1\nmaps: [{{map: x.h5, recordings: [{{path: {lap1}, frames: '5'}}]}}]\n")
    with pytest.raises(LtcError, match=r"at maps.0.recordings.0: --frames '5': not START:STOP"):
        ingest_many(bad)


def test_a_failing_recording_is_reported_and_the_others_go_on(laps, tmp_path):
    lap1, lap2, lap3 = laps
    manifest = write_manifest(tmp_path / "fleet.yaml", f"""\
format: ltc-manifest/1
maps:
  - {{name: site-a, map: a.h5, recordings: [{lap1}, missing-recording, {lap2}]}}
  - {{name: site-b, map: b.h5, recordings: [{lap3}]}}
""")
    r = run("ingest-many", manifest)
    assert r.exit_code == 1, r.output
    lines = r.stdout.strip().splitlines()
    assert lines[0].split() == ["map", "recording", "status", "frames", "skip", "still", "had", "new", "gone",
                                 "objects", "s"]
    assert [ln.split()[2] for ln in lines[1:4]] == ["ok", "failed", "ok"]
    assert lines[4].split()[2] == "ok" and lines[4].split()[0] == "site-b"
    assert lines[5] == f"failed: {tmp_path / 'missing-recording'}: recording does not exist"
    assert lines[6] == f"{manifest}: 4 recordings into 2 maps: 3 ok, 1 failed; 60 frames ingested"
    seq = tmp_path / "seq.h5"
    for lap in (lap1, lap2):
        ingest([lap], seq, defaults())
    assert_same_map(seq, tmp_path / "a.h5")


@pytest.mark.parametrize("text,problem", [
    ("format: ltc-manifest/2\nmaps: [{map: a.h5, recordings: [r]}]\n", "at format: "),
    ("format: ltc-manifest/1\nmaps: [{map: a.h5, recordings: []}]\n", "at maps.0.recordings: "),
    ("format: ltc-manifest/1\nmaps: [{map: a.h5, recordings: [{path: r, time: yesterday}]}]\n",
     "at maps.0.recordings.0"),
    ("format: ltc-manifest/1\nmaps: [{map: a.h5, recordings: [{path: r, time: 2024-05-01}, s]}]\n",
     "at maps.0.recordings: give every recording a time, or none"),
    ("format: ltc-manifest/1\nmaps: [{map: a.h5, recordings: [r]}, {map: ./a.h5, recordings: [s]}]\n",
     "at maps.1: ./a.h5 is the map of maps.0 too"),
    ("format: ltc-manifest/1\nset: [modeling.eps=-1]\nmaps: [{map: a.h5, recordings: [r]}]\n", "modeling.eps"),
])
def test_a_bad_manifest_is_refused_before_any_map_is_touched(tmp_path, text, problem):
    manifest = write_manifest(tmp_path / "fleet.yaml", text)
    r = run("ingest-many", manifest)
    err = r.stderr.strip().splitlines()
    assert r.exit_code == 1 and len(err) == 1, r.output
    assert problem in err[0] and (problem == "modeling.eps" or str(manifest) in err[0]), err[0]
    assert not (tmp_path / "a.h5").exists()

import multiprocessing as mp
import os

import h5py
import numpy as np
import pytest

from ltc_cli.errors import MapFormatError, MapLockedError
from ltc_cli.map.model import ACTIVE, Event, SemanticMap
from ltc_cli.map import store_write
from ltc_cli.map.store import MapLock, load_map, save_map


def small_map():
    smap = SemanticMap.new(["chair", "table"])
    smap.created = "2026-01-01T00:00:00+00:00"
    smap.objects.append(center=[1, 2, 0.5], yaw=0.3, size=[0.5, 0.5, 1.0], visible=np.ones(8, bool),
                        defined=True, scores=[0.7, 0.2, 0.1], n_det=3, status=ACTIVE)
    smap.events.append(Event(0, 4, "abc/000004", "created", 1, 0, ""))
    smap.frame_keys.add("abc/000004")
    smap.sessions.append({"started": "s", "finished": "f", "status": "complete", "sources": "[]",
                          "recordings": "[]", "readers": "[]", "detector": "{}", "metric": "vertex",
                          "policy": "static", "settings": "{}", "v_other": 0.5, "ltc_version": "0",
                          "frames_done": 1, "frames_skipped": 0, "up_rotation": "[]"})
    return smap


def test_round_trip(tmp_path):
    path = tmp_path / "m.h5"
    save_map(small_map(), path)
    back = load_map(path)
    assert back.classes == ["chair", "table"]
    np.testing.assert_array_equal(back.objects.center, [[1, 2, 0.5]])
    np.testing.assert_array_equal(back.objects.scores, [[0.7, 0.2, 0.1]])
    assert back.objects.ids.tolist() == [1]
    assert back.events == small_map().events
    assert back.frame_keys == {"abc/000004"}
    assert back.sessions[0]["metric"] == "vertex" and back.sessions[0]["frames_done"] == 1
    assert not list(tmp_path.glob(".*tmp*"))  # no temporary file left behind
    with h5py.File(path) as f:  # plain HDF5: any reader sees the objects
        assert f.attrs["format"] == "ltc-map"
        np.testing.assert_array_equal(f["objects/yaw"][()], [0.3])


def test_refuses_files_that_are_not_maps(tmp_path):
    junk = tmp_path / "junk.h5"
    junk.write_bytes(b"hello, not hdf5")
    with pytest.raises(MapFormatError, match="not an HDF5 file"):
        load_map(junk)
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f["x"] = 1
    with pytest.raises(MapFormatError, match="not an ltc map"):
        load_map(other)


def test_refuses_a_newer_format_version(tmp_path):
    path = tmp_path / "m.h5"
    save_map(small_map(), path)
    with h5py.File(path, "a") as f:
        f.attrs["format_version"] = 99
    with pytest.raises(MapFormatError, match="newer"):
        load_map(path)


def _hold_lock(path, ready, release):
    with MapLock(path):
        ready.set()
        release.wait(10)


def test_a_second_writer_gets_a_clear_error(tmp_path):
    path = tmp_path / "m.h5"
    ctx = mp.get_context("fork")
    ready, release = ctx.Event(), ctx.Event()
    p = ctx.Process(target=_hold_lock, args=(path, ready, release))
    p.start()
    try:
        assert ready.wait(10)
        with pytest.raises(MapLockedError, match=f"pid {p.pid}"):
            MapLock(path).acquire()
    finally:
        release.set()
        p.join(10)
    # Released when the holder ends (even when killed): the lock can be taken again.
    MapLock(path).acquire().release()
    assert os.path.exists(str(path) + ".lock")


def _same_maps(a, b):
    assert a.classes == b.classes and a.created == b.created
    np.testing.assert_array_equal(a.up_rotation, b.up_rotation)
    ca, cb = a.objects.columns(), b.objects.columns()
    assert ca.keys() == cb.keys()
    for k in ca:
        np.testing.assert_array_equal(ca[k], cb[k], err_msg=k)
    assert a.events == b.events and a.sessions == b.sessions and a.frame_keys == b.frame_keys


def _grow(smap, rng, step):
    """One checkpoint's worth of change: new events (one with a longer detail text than any
    before, so its column is recreated wider), new frame keys, the last session row updated (a new
    one every third step), old objects changed and new ones added."""
    for i in range(int(rng.integers(0, 40))):
        smap.events.append(Event(step, i, f"rec{step}/{i:06d}", "updated", int(rng.integers(1, 9)), 0,
                                 "x" * int(rng.integers(0, 3 + step))))
        smap.frame_keys.add(f"rec{step}/{i:06d}")
    if step % 3 == 0:
        smap.sessions.append(dict(small_map().sessions[0], status="interrupted", frames_done=0))
    smap.sessions[-1]["frames_done"] += 7
    smap.sessions[-1]["settings"] = {"step": step, "long": "y" * step}
    if smap.objects.n:
        rows = rng.integers(0, smap.objects.n, 3)
        smap.objects.cols["center"][rows] += 0.25
        smap.objects.cols["n_det"][rows] += 1
    for _ in range(int(rng.integers(0, 30))):
        smap.objects.append(center=rng.normal(size=3), yaw=float(rng.uniform()), size=[1, 1, 1],
                            visible=np.ones(8, bool), defined=True, scores=rng.dirichlet(np.ones(3)), n_det=1)


@pytest.mark.parametrize("chunk_bytes", [None, 256], ids=["default", "tiny-chunks"])
def test_commits_in_place_load_as_a_whole_rewrite_does(tmp_path, monkeypatch, chunk_bytes):
    """Twenty checkpoints of a growing map, committed in place, load after each one exactly as the
    same map written whole (a second file, in_place=False): objects, events, sessions, frames.
    With tiny chunks every column is chunked (appends, changed chunks, wider text recreated)."""
    if chunk_bytes:
        monkeypatch.setattr(store_write, "CHUNK_BYTES", chunk_bytes)
    rng = np.random.default_rng(11)
    smap = small_map()
    inc, whole = tmp_path / "inc.h5", tmp_path / "whole.h5"
    save_map(smap, inc)
    inode = os.stat(inc).st_ino
    for step in range(1, 21):
        _grow(smap, rng, step)
        save_map(smap, inc)
        save_map(smap, whole, in_place=False)
        assert os.stat(inc).st_ino == inode  # written in place, not replaced by a new file
        _same_maps(load_map(inc), load_map(whole))
        back = load_map(inc)
        assert back.events == smap.events and back.frame_keys == smap.frame_keys
        assert back.sessions[-1]["frames_done"] == smap.sessions[-1]["frames_done"]
    assert not os.path.exists(str(inc) + "-journal")
    with h5py.File(inc) as f:  # plain HDF5 still
        assert f["events/kind"].shape == (len(smap.events),)
        assert (f["events/session"].chunks is not None) == bool(chunk_bytes)

import multiprocessing as mp
import os

import h5py
import numpy as np
import pytest

from ltc_cli.errors import MapFormatError, MapLockedError
from ltc_cli.map.model import ACTIVE, Event, SemanticMap
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

import multiprocessing as mp
import os
import subprocess
import sys
import threading
import time

import h5py
import numpy as np
import pytest

from ltc_cli.errors import MapFormatError, MapLockedError
from ltc_cli.map.model import ACTIVE, Event, SemanticMap
from ltc_cli.map import journal, store_write
from ltc_cli.map.store import MapLock, load_map, load_sessions, save_map
from tests.reliability import remount_read_only, tmpfs


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
        assert f.attrs["format"] == b"ltc-map"  # fixed-length: h5py reads it as bytes
        np.testing.assert_array_equal(f["objects/yaw"][()], [0.3])
    # No variable-length text anywhere, so no global heap collection (signature GCOL), whose
    # damage made HDF5 loop for ever: the last one held the format mark.
    assert b"GCOL" not in path.read_bytes()


def test_the_sessions_alone_are_the_maps_sessions(tmp_path):
    path = tmp_path / "m.h5"
    smap = small_map()
    smap.sessions.append({**smap.sessions[0], "status": "interrupted", "reader_options": '[{"up": "z"}]'})
    save_map(smap, path)
    rows = load_sessions(path)
    assert rows == load_map(path).sessions
    assert [r["status"] for r in rows] == ["complete", "interrupted"]
    # The columns the row did not give are empty, as load_map gives them (text "", numbers 0).
    assert rows[0]["reader_options"] == "" and rows[1]["reader_options"] == '[{"up": "z"}]'
    assert rows[0]["frames_still"] == 0
    junk = tmp_path / "junk.h5"
    junk.write_bytes(b"hello, not hdf5")
    with pytest.raises(MapFormatError, match="not an HDF5 file"):
        load_sessions(junk)
    with h5py.File(path, "a") as f:  # one column a row short: damage, named
        data = f["sessions/status"][()]
        del f["sessions/status"]
        f["sessions/status"] = data[:1]
    with pytest.raises(MapFormatError, match="sessions"):
        load_sessions(path)


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


class _DiesBeforeTheCommitPoint:
    """``os`` for the journal module of a writer killed just before it unlinks its journal."""

    def __getattr__(self, name):
        return getattr(os, name)

    def unlink(self, path):
        os._exit(9)


def _torn_commit(path, saved):
    """In a child: commit a map (whole), keep a copy of the file in ``saved``, then commit a
    changed map in place and die just before the commit point (every byte written)."""
    smap = small_map()
    save_map(smap, path)
    saved.write_bytes(path.read_bytes())
    smap.events.append(Event(1, 5, "abc/000005", "updated", 1, 0, "a longer detail than before"))
    smap.frame_keys.add("abc/000005")
    smap.sessions[0]["frames_done"] = 2
    smap.objects.cols["center"][0] = [3, 3, 3]
    journal.os = _DiesBeforeTheCommitPoint()
    save_map(smap, path)
    os._exit(0)  # not reached


def _kill_a_commit(path, saved):
    p = mp.get_context("fork").Process(target=_torn_commit, args=(path, saved))
    p.start()
    p.join(60)
    assert p.exitcode == 9
    assert os.path.exists(f"{path}-journal") and path.read_bytes() != saved.read_bytes()


def test_a_loaded_map_commits_in_place_unless_the_file_changed_since(tmp_path):
    """A map read from disk (a new session on an old map) commits its first checkpoint in place,
    as the same changes written whole load; if another process replaced the file after the read,
    the commit is whole (a delta against a file it did not read would be wrong)."""
    rng = np.random.default_rng(5)
    path, whole = tmp_path / "m.h5", tmp_path / "whole.h5"
    save_map(small_map(), path)
    for step in (1, 2):
        _grow(small_map(), rng, step)  # nothing committed by this map: the file is unchanged
        smap = load_map(path)
        inode = os.stat(path).st_ino
        _grow(smap, rng, step)
        save_map(smap, path)
        assert os.stat(path).st_ino == inode
        save_map(smap, whole, in_place=False)
        _same_maps(load_map(path), load_map(whole))
    smap = load_map(path)
    other = load_map(path)
    _grow(other, rng, 3)
    save_map(other, path)  # in place: the file smap read is no longer the file there
    _grow(smap, rng, 4)
    inode = os.stat(path).st_ino
    save_map(smap, path)
    assert os.stat(path).st_ino != inode  # written whole
    save_map(smap, whole, in_place=False)
    _same_maps(load_map(path), load_map(whole))


def test_a_map_without_free_space_records_is_written_whole_first(tmp_path, monkeypatch):
    """A file that does not keep its free-space records (maps of ltc before commits in place)
    would lose every rewritten dataset's old space if patched: its first commit is whole (a new
    inode, the same content as a whole write), and the commits after it are in place."""
    path, whole = tmp_path / "m.h5", tmp_path / "whole.h5"
    monkeypatch.setattr(store_write, "FILE_OPTIONS", {"libver": ("v108", "latest")})
    save_map(small_map(), path)
    monkeypatch.undo()
    with h5py.File(path) as f:
        assert f.id.get_create_plist().get_file_space_strategy()[1] == 0
    rng = np.random.default_rng(7)
    smap = load_map(path)
    for step, replaced in ((1, True), (2, False)):
        inode = os.stat(path).st_ino
        _grow(smap, rng, step)
        save_map(smap, path)
        assert (os.stat(path).st_ino != inode) == replaced
        save_map(smap, whole, in_place=False)
        _same_maps(load_map(path), load_map(whole))


@pytest.mark.parametrize("through", ["the map", "a symlink"])
def test_a_hot_journal_is_rolled_back_by_the_next_reader(tmp_path, through):
    path, saved = tmp_path / "m.h5", tmp_path / "saved.bin"
    _kill_a_commit(path, saved)
    link = tmp_path / "link.h5"
    link.symlink_to("m.h5")
    back = load_map(path if through == "the map" else link)
    assert back.frame_keys == {"abc/000004"} and back.events == small_map().events
    assert path.read_bytes() == saved.read_bytes()  # byte for byte the previous commit
    assert not os.path.exists(f"{path}-journal")


def test_an_incomplete_journal_is_removed_and_the_map_left_as_it_is(tmp_path):
    path = tmp_path / "m.h5"
    save_map(small_map(), path)
    before = path.read_bytes()
    jp = tmp_path / "m.h5-journal"
    jp.write_bytes(b"LTCJRNL1" + bytes(100))  # its checksum does not hold: never completed
    assert load_map(path).frame_keys == {"abc/000004"}
    assert not jp.exists() and path.read_bytes() == before


def test_a_hot_journal_in_a_read_only_folder_is_read_around(tmp_path):
    """The journal cannot be rolled back where nothing can be written: ltc reads the map as the
    journal restores it, in memory, and leaves both files for a writer."""
    with tmpfs(tmp_path / "fs", 1024) as fs:
        path, saved = fs / "m.h5", tmp_path / "saved.bin"
        _kill_a_commit(path, saved)
        torn = path.read_bytes()
        remount_read_only(fs)
        back = load_map(path)
        assert back.frame_keys == {"abc/000004"} and back.events == small_map().events
        np.testing.assert_array_equal(back.objects.center, [[1, 2, 0.5]])
        assert path.read_bytes() == torn and os.path.exists(f"{path}-journal")


# A reader holding the map as load_map does while it reads, until its stdin closes.
HOLD_SHARED = ("import fcntl, os, sys; fd = os.open(sys.argv[1], os.O_RDONLY); fcntl.flock(fd, fcntl.LOCK_SH); "
               "print('ready', flush=True); sys.stdin.read()")


def _waiting_for_a_lock(inode: int) -> bool:
    with open("/proc/locks") as fh:  # "N: -> FLOCK ADVISORY WRITE pid maj:min:inode ...": a blocked request
        return any("->" in ln and ln.split()[6].endswith(f":{inode}") for ln in fh)


def test_a_commit_in_place_waits_for_readers(tmp_path):
    """While an ltc reader holds the map, an in-place commit waits before it writes anything (not
    even its journal): the reader sees whole commits only."""
    path = tmp_path / "m.h5"
    smap = small_map()
    save_map(smap, path)
    smap.frame_keys.add("abc/000005")
    before = path.read_bytes()
    reader = subprocess.Popen([sys.executable, "-c", HOLD_SHARED, str(path)], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, text=True)
    try:
        assert reader.stdout.readline() == "ready\n"
        writer = threading.Thread(target=save_map, args=(smap, path))
        writer.start()
        for _ in range(3000):  # until the writer's lock request is queued behind the reader's
            if _waiting_for_a_lock(os.stat(path).st_ino):
                break
            time.sleep(0.01)
        else:
            pytest.fail("the commit never waited for the reader")
        assert path.read_bytes() == before and not os.path.exists(f"{path}-journal")
    finally:
        reader.communicate("")
    writer.join(30)
    assert load_map(path).frame_keys == {"abc/000004", "abc/000005"}


def test_a_journal_without_its_map_is_removed_before_a_new_map_is_made(tmp_path):
    path = tmp_path / "m.h5"
    (tmp_path / "m.h5-journal").write_bytes(b"left beside a map since deleted")
    save_map(small_map(), path)
    assert load_map(path).frame_keys == {"abc/000004"} and not (tmp_path / "m.h5-journal").exists()

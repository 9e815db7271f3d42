"""Reliability (docs/reliability.md): a full disk, leftover temporary files, symlinks, permissions,
many detections in one frame, and damaged maps. Every failure is one line on stderr, exit 1, no
traceback, and the old map byte-identical (sha256 before and after)."""

import errno
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

import ltc_cli.fileio as fileio
import ltc_cli.map.journal as journal
from ltc_cli.errors import MapLockedError
from ltc_cli.map.store import MapLock, load_map
from ltc_cli.pipeline import clustering
from ltc_cli.pipeline.clustering import GROUPS_PER_PASS, dbscan_labels, grid_dbscan_labels, largest_clusters
from ltc_cli.pipeline.mapper import Mapper
from tests.reliability import (error_line, fill_to, many_instances, remount_read_only, run, sha256, temp_files,
                               tiny_house, tmpfs)

ROOT = Path(__file__).resolve().parent.parent
NO_SPACE = re.compile(r"^Error: (.*): not enough free space to commit \(need ([\d.]+) MB, ([\d.]+) MB free\); "
                      r"the map is unchanged$")


@pytest.fixture(scope="module")
def house(tmp_path_factory):
    return tiny_house(tmp_path_factory.mktemp("house"))


@pytest.fixture(scope="module")
def lap1_map(house, tmp_path_factory):
    m = tmp_path_factory.mktemp("lap1map") / "map.h5"
    r = run("ingest", house / "lap1", "--map", m)
    assert r.exit_code == 0, r.output
    return m


def copy_map(lap1_map, folder, name="map.h5") -> Path:
    m = Path(folder) / name
    shutil.copyfile(lap1_map, m)
    return m


@pytest.fixture
def no_frame_mapped(monkeypatch):
    """Fails the run if any frame reaches the mapper: the refusal must come up front."""
    def refuse(*args, **kwargs):
        raise AssertionError("a frame was mapped before the refusal")
    monkeypatch.setattr(Mapper, "process_frame", refuse)


# -- 1. a full disk ----------------------------------------------------------------------------

@pytest.mark.parametrize("how", ["checked before writing", "ENOSPC while reserving", "ENOSPC mid-write"])
def test_a_full_disk_refuses_the_commit_in_one_line(house, lap1_map, tmp_path, monkeypatch, how):
    with tmpfs(tmp_path / "fs", 256) as fs:
        m = copy_map(lap1_map, fs)
        (fs / "map.h5.lock").write_text("0")  # its page taken now, not after the filling
        size = m.stat().st_size
        # Room for a map as large as the old one (so the up-front check passes and lap 2 is mapped),
        # not for the larger map lap 2 makes.
        fill_to(fs, -(-size // 4096) * 4096)
        if how != "checked before writing":  # the free-space check is fooled: the kernel says no
            monkeypatch.setattr(fileio, "free_bytes", lambda folder: 1 << 40)
        if how == "ENOSPC mid-write":  # ... and no reservation either: os.write fails part-way
            monkeypatch.setattr(fileio, "_reserve", lambda fd, size: None)
        before = sha256(m)
        r = run("ingest", house / "lap2", "--map", m)
        line = error_line(r)
        match = NO_SPACE.match(line)
        assert match and match.group(1) == str(m), line
        need, free = float(match.group(2)), float(match.group(3))
        assert need > size / 1e6 and need > free  # the commit of the larger lap-2 map was refused
        assert sha256(m) == before
        assert temp_files(fs) == []  # nothing left to fill the disk
        assert len(load_map(m).sessions) == 1


def test_too_little_space_for_any_commit_is_refused_up_front(house, lap1_map, tmp_path, no_frame_mapped):
    with tmpfs(tmp_path / "fs", 256) as fs:
        m = copy_map(lap1_map, fs)
        fill_to(fs, 4096)
        before = sha256(m)
        line = error_line(run("ingest", house / "lap2", "--map", m))
        match = NO_SPACE.match(line)
        assert match and float(match.group(2)) == pytest.approx(m.stat().st_size / 1e6, rel=1e-2), line
        assert sha256(m) == before and temp_files(fs) == []


class _DiskFullOs:
    """``os`` for the fileio module with a disk that fills after a few bytes (no mount needed)."""

    def __getattr__(self, name):
        return getattr(os, name)

    def posix_fallocate(self, fd, offset, size):
        raise OSError(errno.EOPNOTSUPP, "not supported")

    def write(self, fd, data):
        if len(data) > 100:
            os.write(fd, bytes(data[:100]))
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return os.write(fd, data)


def test_enospc_part_way_through_a_write_leaves_nothing_behind(house, lap1_map, tmp_path, monkeypatch):
    m = copy_map(lap1_map, tmp_path)
    before = sha256(m)
    monkeypatch.setattr(fileio, "os", _DiskFullOs())  # a whole commit
    monkeypatch.setattr(journal, "os", _DiskFullOs())  # a commit in place (its journal)
    line = error_line(run("ingest", house / "lap2", "--map", m))
    assert NO_SPACE.match(line), line
    assert sha256(m) == before and temp_files(tmp_path) == []


class _InPlaceDiskFullOs:
    """``os`` for the journal module with a full disk at one step of an in-place commit."""

    def __init__(self, how):
        self.how = how

    def __getattr__(self, name):
        return getattr(os, name)

    def write(self, fd, data):  # the journal
        if self.how == "ENOSPC writing the journal" and len(data) > 100:
            os.write(fd, bytes(data[:100]))
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return os.write(fd, data)

    def posix_fallocate(self, fd, offset, size):
        if self.how == "ENOSPC reserving the growth":
            os.ftruncate(fd, offset + size // 2)  # a reservation that got part of the way
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        raise OSError(errno.EOPNOTSUPP, "not supported")

    def pwrite(self, fd, data, offset):  # no reservation: the growth fails part-way
        if self.how == "ENOSPC mid in-place write" and offset + len(data) > os.fstat(fd).st_size:
            os.pwrite(fd, bytes(data[:10]), offset)
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return os.pwrite(fd, data, offset)


@pytest.mark.parametrize("how", ["checked before writing", "ENOSPC writing the journal", "ENOSPC reserving the growth",
                                 "ENOSPC mid in-place write"])
def test_a_full_disk_at_a_commit_in_place_leaves_the_last_commit(house, lap1_map, tmp_path, monkeypatch, how):
    """The disk fills before the session's first checkpoint, which goes in place like every later
    one (the map read at the start is its base): one line, the map exactly as lap 1 left it, no
    journal left; a resume ends in the uninterrupted run's map."""
    ref = copy_map(lap1_map, tmp_path, "ref.h5")
    assert run("ingest", house / "lap2", "--map", ref).exit_code == 0
    m = copy_map(lap1_map, tmp_path)
    lap1_frames = len(load_map(m).frame_keys)
    if how == "checked before writing":
        monkeypatch.setattr(journal, "free_bytes", lambda folder: 0)
    else:
        monkeypatch.setattr(journal, "os", _InPlaceDiskFullOs(how))
    line = error_line(run("ingest", house / "lap2", "--map", m, "--checkpoint-every", "1"))
    match = NO_SPACE.match(line)
    assert match and match.group(1) == str(m), line
    assert len(load_map(m).frame_keys) == lap1_frames  # the first checkpoint failed, in place
    assert not (tmp_path / "map.h5-journal").exists() and temp_files(tmp_path) == []
    monkeypatch.undo()
    assert run("ingest", house / "lap2", "--map", m).exit_code == 0
    a, b = load_map(m), load_map(ref)
    for k, col in b.objects.columns().items():
        np.testing.assert_array_equal(a.objects.columns()[k], col, err_msg=k)
    assert a.events == b.events and a.frame_keys == b.frame_keys
    assert [s["status"] for s in a.sessions] == ["complete", "complete"]


# -- 2. temporary files left by killed writers ---------------------------------------------------

def test_leftover_temp_files_are_reported_by_info_and_removed_by_the_next_writer(house, lap1_map, tmp_path):
    m = copy_map(lap1_map, tmp_path)
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    dead_pid = int(dead.stdout)
    stale = tmp_path / f".map.h5.tmp-{dead_pid}"
    stale.write_bytes(b"\0" * 5000)
    live = subprocess.Popen([sys.executable, "-c", "import sys; sys.stdin.read()"], stdin=subprocess.PIPE)
    try:
        busy = tmp_path / f".map.h5.tmp-{live.pid}"
        busy.write_bytes(b"x")
        r = run("info", m)
        assert r.exit_code == 0
        warnings = [ln for ln in r.stderr.splitlines() if ln.strip()]
        assert len(warnings) == 1 and warnings[0].startswith(f"warning: {stale}: ") and "5000 bytes" in warnings[0]
        assert "interrupted write" in warnings[0] and str(busy) not in r.stderr
        r = run("info", m, "--format", "json")
        assert '"temp_files": [\n    "' + str(stale) + '"\n  ]' in r.stdout
        # The next writer holds the lock: no other process writes this map, so every temp file goes.
        r = run("ingest", house / "lap2", "--map", m)
        assert r.exit_code == 0, r.output
        assert temp_files(tmp_path) == []
    finally:
        live.communicate(b"")


def test_a_leftover_temp_file_that_fills_the_disk_no_longer_blocks_every_ingest(house, lap1_map, tmp_path):
    with tmpfs(tmp_path / "fs", 256) as fs:
        m = copy_map(lap1_map, fs)
        dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
        fill_to(fs, 4096)
        os.rename(fs / "ballast", fs / f".map.h5.tmp-{int(dead.stdout)}")  # the killed writer's file
        r = run("ingest", house / "lap2", "--map", m)
        assert r.exit_code == 0, r.output
        assert temp_files(fs) == [] and len(load_map(m).sessions) == 2


# -- 3. symlinks ----------------------------------------------------------------------------------

def test_a_map_reached_by_a_symlink_is_one_map(house, lap1_map, tmp_path):
    real = copy_map(lap1_map, tmp_path, "real.h5")
    link = tmp_path / "link.h5"
    link.symlink_to("real.h5")
    before = sha256(real)
    with MapLock(real):
        line = error_line(run("ingest", house / "lap2", "--map", link))
    assert f"{link}: another ltc process (pid {os.getpid()}) is writing this map" in line
    assert sha256(real) == before
    with MapLock(link):
        with pytest.raises(MapLockedError, match="another ltc process"):
            MapLock(real).acquire()
    r = run("ingest", house / "lap2", "--map", link)
    assert r.exit_code == 0, r.output
    assert link.is_symlink() and os.readlink(link) == "real.h5"  # still a link, to the updated map
    assert sha256(real) != before and len(load_map(real).sessions) == 2
    assert not (tmp_path / "link.h5.lock").exists() and temp_files(tmp_path) == []
    # A link to a map that does not exist yet: the map is made where the link points.
    new_link = tmp_path / "new-link.h5"
    new_link.symlink_to("new.h5")
    assert run("ingest", house / "lap1", "--map", new_link).exit_code == 0
    assert new_link.is_symlink() and len(load_map(tmp_path / "new.h5").frame_keys) == 12


# -- 4. permissions -------------------------------------------------------------------------------

def test_a_read_only_map_is_refused_up_front(house, lap1_map, tmp_path, no_frame_mapped):
    m = copy_map(lap1_map, tmp_path)
    m.chmod(0o444)
    before = sha256(m)
    line = error_line(run("ingest", house / "lap2", "--map", m))
    assert line == f"Error: {m}: the map file is read-only (mode 0444); make it writable (chmod u+w) to ingest into it"
    assert sha256(m) == before and (m.stat().st_mode & 0o777) == 0o444


@pytest.mark.parametrize("lock_exists", [False, True], ids=["first-write", "lock-file-left"])
def test_a_folder_that_is_not_writable_is_refused_up_front(house, lap1_map, tmp_path, no_frame_mapped, lock_exists):
    with tmpfs(tmp_path / "fs", 256) as fs:
        m = copy_map(lap1_map, fs)
        if lock_exists:
            (fs / "map.h5.lock").write_text("")
        before = sha256(m)
        remount_read_only(fs)
        line = error_line(run("ingest", house / "lap2", "--map", m))
        assert line == (f"Error: {fs}: the map's folder is not writable (Read-only file system); ltc writes each "
                        "commit as a new file beside the map")
        assert sha256(m) == before


def test_a_commit_keeps_the_map_file_mode(house, lap1_map, tmp_path):
    m = copy_map(lap1_map, tmp_path)
    m.chmod(0o640)
    assert run("ingest", house / "lap2", "--map", m).exit_code == 0
    assert (m.stat().st_mode & 0o777) == 0o640 and len(load_map(m).sessions) == 2


# -- 5. many detections in one frame --------------------------------------------------------------

def _blobs(n_groups, seed=0):
    """Per group: a blob of 40 points, a smaller blob of 25 a metre away, and 3 stray points; all
    groups overlap in space (only the group id keeps them apart)."""
    rng = np.random.default_rng(seed)
    pts, group = [], []
    for g in range(n_groups):
        c = rng.uniform(-2, 2, 3)
        pts += [c + rng.normal(0, 0.03, (40, 3)), c + [1, 0, 0] + rng.normal(0, 0.03, (25, 3)),
                c + rng.uniform(-3, 3, (3, 3))]
        group.append(np.full(68, g))
    return np.concatenate(pts), np.concatenate(group)


@pytest.mark.parametrize("method", ["grid", "voxel", "dbscan"])
@pytest.mark.parametrize("limit", ["groups", "points", "key width"])
def test_more_detections_than_one_pass_takes_cluster_as_each_alone(method, limit, monkeypatch):
    n = GROUPS_PER_PASS + 300  # two passes of the grid methods
    if limit == "points":  # passes of at most 1,000 points (15 detections)
        monkeypatch.setattr(clustering, "POINTS_PER_PASS", 1000)
        n = 200
    elif limit == "key width":  # 4 m of points need more than 2^5 cells: parts are halved
        monkeypatch.setattr(clustering, "_AXIS_BITS", 5)
        n = 60
    pts, group = _blobs(n)
    together = largest_clusters(pts, group, 0.15, 20, method)
    for g in range(n):
        idx = np.flatnonzero(group == g)
        alone = largest_clusters(pts[idx], np.zeros(len(idx), int), 0.15, 20, method)[0]
        np.testing.assert_array_equal(together[g], idx[alone])
        assert len(together[g]) >= 38  # the 40-point blob, not the 25-point one


def test_points_kilometres_apart_keep_their_clusters():
    """Two dense blobs 20 km apart in one detection: too wide for packed cell keys until the empty
    kilometres are compacted. The clusters are exact DBSCAN's (a KD-tree, no grid)."""
    rng = np.random.default_rng(1)
    pts = np.concatenate([rng.normal(0, 0.03, (60, 3)), [20_000.0, 0, 0] + rng.normal(0, 0.03, (30, 3))])
    group = np.zeros(len(pts), int)
    exact = dbscan_labels(pts, 0.15, 20)
    assert sorted(np.bincount(exact)) == [30, 60]
    grid = grid_dbscan_labels(pts, group, 0.15, 20)
    assert (grid[:60] == grid[0]).all() and (grid[60:] == grid[60]).all() and grid[0] != grid[60] and grid[0] >= 0
    np.testing.assert_array_equal(largest_clusters(pts, group, 0.15, 20, "grid")[0], np.arange(60))


def test_three_thousand_instances_in_one_frame(tmp_path):
    rec = many_instances(tmp_path / "rec", 3000)
    det_file = rec / "detections" / "000000.json"
    m = tmp_path / "all.h5"
    # One frame is one view, and each square one detection (two masks of one image are two
    # instances: association.adjoin_same_frame): the confirmation would leave nothing to look at.
    one_view = ("--set", "maintenance.min_detection_views=null", "--set", "maintenance.min_detections=1")
    r = run("ingest", rec, "--map", m, "--set", "modeling.max_detections=5000", *one_view)
    assert r.exit_code == 0 and r.stderr.strip() == "", r.output
    assert "1 frame ingested" in r.stdout
    assert len(load_map(m).active_rows()) > 0
    # Over the cap: a warning naming the file, and the most confident detections used.
    capped = tmp_path / "capped.h5"
    r = run("ingest", rec, "--map", capped, "--set", "modeling.max_detections=100", *one_view)
    assert r.exit_code == 0, r.output
    warnings = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert warnings == [f"warning: {det_file}: 3000 detections in one frame, more than modeling.max_detections "
                        "(100); kept the 100 most confident"]
    # The 100 most confident are the first squares: image rows 0-9 (64 squares a row), which lie
    # at least (119.5 - 9) * 4 m / 250 px above the camera (1 m). Every box of the map is there.
    z_lowest = 1 + (119.5 - 9) * 4.0 / 250
    centers = load_map(capped).objects.center
    assert len(centers) and (centers[:, 2] > z_lowest - 0.05).all()


# -- 9. damaged maps ------------------------------------------------------------------------------

def _replace(f, name, data):
    del f[name]
    f[name] = data


DAMAGES = {
    "truncated": (lambda p: p.write_bytes(p.read_bytes()[: p.stat().st_size // 2]), "truncated or damaged"),
    "truncated-head": (lambda p: p.write_bytes(p.read_bytes()[:200]), "truncated or damaged"),
    "event-log-cut": (lambda f: _replace(f, "events/kind", f["events/kind"][:1]),
                      "the events columns have different lengths (events/kind has 1, the others"),
    "frames-integers": (lambda f: _replace(f, "frames", np.arange(len(f["frames"]))),
                        "frames holds integers, not frame keys (text)"),
    "up-rotation-shape": (lambda f: _replace(f, "up_rotation", np.zeros(2)),
                          "up_rotation has shape (2,); expected a 3x3 rotation"),
    "up-rotation-not-rotation": (lambda f: _replace(f, "up_rotation", np.eye(3) * 2), "up_rotation is not a rotation"),
    "center-n-by-2": (lambda f: _replace(f, "objects/center", f["objects/center"][:, :2]),
                      "objects/center has shape"),
    "format-version-text": (lambda f: f.attrs.__setitem__("format_version", "one"),
                            "format_version is 'one', not an integer"),
    "scores-nan": (lambda f: f["objects/scores"].__setitem__(Ellipsis, np.nan),
                   "objects/scores holds values that are not finite"),
    "missing-dataset": (lambda f: f.__delitem__("objects/size"), "the dataset objects/size is missing"),
    "missing-group": (lambda f: f.__delitem__("events"), "the group events is missing"),
    "newer-version": (lambda f: f.attrs.__setitem__("format_version", 2),
                      "map format version 2 is newer than this ltc reads (1); upgrade ltc"),
}


@pytest.mark.parametrize("damage", list(DAMAGES))
def test_a_damaged_map_is_refused_in_one_line_and_never_written_over(house, lap1_map, tmp_path, damage):
    m = copy_map(lap1_map, tmp_path)
    change, expected = DAMAGES[damage]
    if damage.startswith("truncated"):
        change(m)
    else:
        with h5py.File(m, "a") as f:
            change(f)
    before = sha256(m)
    for args in (("info", m), ("query", m), ("ingest", house / "lap2", "--map", m)):
        line = error_line(run(*args))
        assert line.startswith(f"Error: {m}: ") and expected in line, line
    assert sha256(m) == before and temp_files(tmp_path) == []


FUZZ = """
import signal, sys
import numpy as np
from ltc_cli.errors import MapFormatError
from ltc_cli.map.store import load_map
data = open(sys.argv[1], "rb").read()
rng = np.random.default_rng(7)
loaded = refused = 0
for i in range(300):
    signal.alarm(20)  # a damaged file must never make HDF5 loop for ever
    if i % 3 == 0:
        damaged = data[: int(rng.integers(0, len(data)))]
    else:
        b = bytearray(data)
        for _ in range(int(rng.integers(1, 8))):
            b[int(rng.integers(0, len(b)))] = int(rng.integers(0, 256))
        damaged = bytes(b)
    open(sys.argv[2], "wb").write(damaged)
    try:
        load_map(sys.argv[2])
        loaded += 1
    except MapFormatError:
        refused += 1
print(loaded, refused)
"""


def test_random_damage_is_refused_or_harmless_never_a_crash(lap1_map, tmp_path):
    """300 seeded truncations and byte changes: each map loads (the change hit values or padding)
    or is refused with MapFormatError; never a crash, a hang or another exception (a subprocess,
    so that a segfault in HDF5 would show as one)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    p = subprocess.run([sys.executable, "-c", FUZZ, str(lap1_map), str(tmp_path / "fz.h5")],
                       capture_output=True, text=True, env=env, timeout=600)
    assert p.returncode == 0, p.stderr[-2000:]
    loaded, refused = map(int, p.stdout.split())
    assert loaded + refused == 300 and refused > 200

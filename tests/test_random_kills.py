"""SIGKILL at 20 random points of a second session on an existing map: every time the map opens,
and a resume ends in exactly the map of an uninterrupted run (DESIGN.md section 4).

The kill points are numbered by a test plugin (tests/kill_points.py) inside the ingest process:
between frames, and at every step of every commit (temporary file created, space reserved, half
written, fsync, just before and just after ``os.replace``). A first run, uninterrupted, lists them;
then 20 of them, drawn with a fixed seed, each kill a fresh copy of the lap-1 map's second session
(``--checkpoint-every 1``, so that commits are many). No timing is involved: the process kills
itself when it reaches its point, and the test waits for its exit.
"""

import os
import shutil
import signal
import subprocess
import sys
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from ltc_cli.map.store import load_map
from tests.reliability import run, temp_files, tiny_house

ROOT = Path(__file__).resolve().parent.parent
KILLS = 20


def ingest_process(rec, m, **env_extra):
    env = dict(os.environ, LTC_PLUGINS="tests.kill_points", **env_extra)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
    return subprocess.run([sys.executable, "-m", "ltc_cli.cli", "ingest", str(rec), "--map", str(m),
                           "--checkpoint-every", "1"], env=env, capture_output=True, text=True, timeout=300)


def state(path):
    smap = load_map(path)
    return smap.objects.columns(), smap.events, smap.frame_keys, [s["status"] for s in smap.sessions]


@pytest.mark.slow
def test_sigkill_at_random_points_of_a_second_session(tmp_path):
    house = tiny_house(tmp_path / "house")
    base = tmp_path / "lap1.h5"
    assert run("ingest", house / "lap1", "--map", base).exit_code == 0
    lap1_frames = len(load_map(base).frame_keys)

    # The uninterrupted second session, listing its kill points.
    ref = tmp_path / "ref.h5"
    shutil.copyfile(base, ref)
    events = tmp_path / "events.txt"
    p = ingest_process(house / "lap2", ref, LTC_TEST_EVENTS=str(events))
    assert p.returncode == 0, p.stderr
    points = events.read_text().splitlines()
    ref_cols, ref_events, ref_frames, ref_status = state(ref)
    assert ref_status == ["complete", "complete"]

    rng = np.random.default_rng(2024)
    chosen = sorted(rng.choice(len(points), size=KILLS, replace=False) + 1)
    kinds = Counter(points[i - 1] for i in chosen)
    assert len(kinds) >= 4, kinds  # kills between frames and inside commits
    m = tmp_path / "map.h5"
    for at in chosen:
        shutil.copyfile(base, m)
        p = ingest_process(house / "lap2", m, LTC_TEST_KILL_AT=str(at))
        assert p.returncode == -signal.SIGKILL, (at, points[at - 1], p.returncode, p.stderr)
        # The map opens, with lap 1 and the frames of the last commit.
        frames = len(load_map(m).frame_keys)
        assert lap1_frames <= frames <= len(ref_frames), (at, points[at - 1])
        r = run("ingest", house / "lap2", "--map", m)
        assert r.exit_code == 0, (at, points[at - 1], r.output)
        cols, ev, keys, status = state(m)
        for k in ref_cols:
            np.testing.assert_array_equal(cols[k], ref_cols[k], err_msg=f"{k} after a kill at {at} ({points[at - 1]})")
        assert ev == ref_events and keys == ref_frames, (at, points[at - 1])
        assert status == ["complete", "complete"]  # the interrupted session was resumed, not doubled
        assert temp_files(tmp_path) == []  # the resume removed what the kill left


def _frames_committed(points, at):
    """Lap-2 frames in the map after a kill at point ``at`` (1-based): the frames detected before
    it, less the one whose commit the kill interrupted unless that commit got past its commit
    point (the journal's unlink, or the whole file's replace)."""
    done = points[:at]
    last = len(done) - 1 - done[::-1].index("detect")
    return done.count("detect") - (not {"after journal unlink", "after replace"} & set(done[last + 1:]))


@pytest.mark.slow
def test_sigkill_at_every_step_of_a_commit_in_place(tmp_path):
    """A kill at each step of one in-place commit (and at the growth's reservation): the map opens
    (ltc rolls the journal back) as exactly the previous commit, or the new one once the journal
    is gone; the journal is gone after the first ltc reader; a resume ends in the uninterrupted
    run's map."""
    house = tiny_house(tmp_path / "house")
    base, ref, events = tmp_path / "lap1.h5", tmp_path / "ref.h5", tmp_path / "events.txt"
    assert run("ingest", house / "lap1", "--map", base).exit_code == 0
    shutil.copyfile(base, ref)
    assert ingest_process(house / "lap2", ref, LTC_TEST_EVENTS=str(events)).returncode == 0
    lap1_frames, points = len(load_map(base).frame_keys), events.read_text().splitlines()
    ref_cols, ref_events, ref_frames, _ = state(ref)
    third = [i for i, p in enumerate(points) if p == "journal created"][2]
    end = points.index("detect", third)
    chosen = list(range(third + 1, end + 1)) + [points.index("growth reserved") + 1]
    assert {points[i - 1] for i in chosen} == {
        "journal created", "journal half written", "after fsync (journal or map)", "fsync", "growth reserved",
        "in place, half written", "before truncate", "after truncate", "before journal unlink",
        "after journal unlink"}
    m = tmp_path / "map.h5"
    journal = tmp_path / "map.h5-journal"
    for at in chosen:
        shutil.copyfile(base, m)
        p = ingest_process(house / "lap2", m, LTC_TEST_KILL_AT=str(at))
        assert p.returncode == -signal.SIGKILL, (at, points[at - 1], p.stderr)
        frames = len(load_map(m).frame_keys)
        assert frames == lap1_frames + _frames_committed(points, at), (at, points[at - 1])
        assert not journal.exists()
        r = run("ingest", house / "lap2", "--map", m)
        assert r.exit_code == 0, (at, points[at - 1], r.output)
        cols, ev, keys, status = state(m)
        for k in ref_cols:
            np.testing.assert_array_equal(cols[k], ref_cols[k], err_msg=f"{k} after a kill at {points[at - 1]}")
        assert ev == ref_events and keys == ref_frames and status == ["complete", "complete"], points[at - 1]

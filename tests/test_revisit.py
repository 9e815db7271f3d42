"""``ltc ingest --revisit``: a recording already in the map driven again as a new session, with frame
keys of its own, resumable when interrupted, and no change to a plain re-run."""

import json
from pathlib import Path

import h5py
import numpy as np
from click.testing import CliRunner

from ltc_cli.cli import cli
from ltc_cli.config import defaults
from ltc_cli.ingest.session import ingest
from ltc_cli.map.store import load_map
from tests.recording import write_recording

LAP1 = Path(__file__).resolve().parent.parent / "sample_data" / "lap1"
N_FRAMES = 76  # frames of sample_data/lap1 (lines of its poses.txt)


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args], catch_exceptions=False)


def assert_same_map(a, b):
    ma, mb = load_map(a), load_map(b)
    for k, v in ma.objects.columns().items():
        np.testing.assert_array_equal(v, mb.objects.columns()[k], err_msg=k)
    np.testing.assert_array_equal(ma.objects.ids, mb.objects.ids)
    assert ma.events == mb.events
    assert ma.frame_keys == mb.frame_keys


def test_revisit_maps_the_lap_again_as_a_new_session(tmp_path):
    m = tmp_path / "map.h5"
    assert run("ingest", LAP1, "--map", m).exit_code == 0
    first = load_map(m)
    r = run("ingest", LAP1, "--map", m, "--revisit")
    assert r.exit_code == 0, r.output
    assert f"{N_FRAMES} frames ingested, 0 skipped, 0 already in the map" in r.output and "visit 2" in r.output
    smap = load_map(m)
    assert [s["visit"] for s in smap.sessions] == [1, 2]
    assert [s["frames_done"] for s in smap.sessions] == [N_FRAMES, N_FRAMES]
    # Visit 2 keys every frame of visit 1 again, as IDENTITY@2/FRAME, beside the first visit's keys.
    assert len(first.frame_keys) == N_FRAMES and first.frame_keys <= smap.frame_keys
    identity = next(iter(first.frame_keys)).split("/")[0]
    assert smap.frame_keys - first.frame_keys == {k.replace(f"{identity}/", f"{identity}@2/") for k in first.frame_keys}
    # The frames were mapped again: the second session logged its own events on visit-2 frames.
    new = smap.events[len(first.events):]
    assert new and all(e.session == 1 for e in new)
    assert {e.kind for e in new} >= {"updated", "non-detection"}
    assert all(f"{identity}@2/" in e.frame_key for e in new if e.frame_key != "end of session")
    assert "visit 2" in run("info", m).output
    # A plain re-run is still a no-op: every first-visit frame is in the map, the file is not rewritten.
    before = m.read_bytes()
    r = run("ingest", LAP1, "--map", m)
    assert r.exit_code == 0 and f"0 frames ingested, 0 skipped, {N_FRAMES} already in the map" in r.output
    assert m.read_bytes() == before
    # Each --revisit is one more visit.
    r = run("ingest", LAP1, "--map", m, "--revisit")
    assert "visit 3" in r.output and [s["visit"] for s in load_map(m).sessions] == [1, 2, 3]


def test_interrupted_revisit_resumes_and_ends_identical(tmp_path):
    ref = tmp_path / "ref.h5"
    ingest([LAP1], ref, defaults())
    ingest([LAP1], ref, defaults(), revisit=True)

    m = tmp_path / "map.h5"
    ingest([LAP1], m, defaults())
    done = []
    s = ingest([LAP1], m, defaults(), revisit=True, checkpoint_every=7,
               on_frame=lambda summary: done.append(1), should_stop=lambda: len(done) >= 30)
    assert s.interrupted and s.frames_done == 30 and s.visit == 2
    smap = load_map(m)
    assert [(x["status"], x["visit"], x["frames_done"]) for x in smap.sessions] == [
        ("complete", 1, N_FRAMES), ("interrupted", 2, 30)]
    # A plain re-run does not touch the interrupted revisit.
    before = m.read_bytes()
    r = run("ingest", LAP1, "--map", m)
    assert r.exit_code == 0 and "0 frames ingested" in r.output and m.read_bytes() == before
    # The same command again resumes the revisit (not a third visit) ...
    r = run("ingest", LAP1, "--map", m, "--revisit")
    assert r.exit_code == 0, r.output
    assert f"{N_FRAMES - 30} frames ingested, 0 skipped, 30 already in the map" in r.output and "visit 2" in r.output
    smap = load_map(m)
    assert [(x["status"], x["visit"], x["frames_done"]) for x in smap.sessions] == [
        ("complete", 1, N_FRAMES), ("complete", 2, N_FRAMES)]
    # ... and ends in the map an uninterrupted revisit makes: objects, ids, events, frame keys.
    assert_same_map(ref, m)


def test_revisit_of_a_new_recording_is_its_first_visit(tmp_path):
    rec = write_recording(tmp_path / "rec")
    m = tmp_path / "map.h5"
    r = run("ingest", rec, "--map", m, "--revisit")
    assert r.exit_code == 0 and "5 frames ingested" in r.output and "; visit" not in r.output
    assert [s["visit"] for s in load_map(m).sessions] == [1]
    r = run("ingest", rec, "--map", m)
    assert "0 frames ingested" in r.output and "5 already in the map" in r.output


def test_maps_without_visits_read_as_first_visits(tmp_path):
    rec = write_recording(tmp_path / "rec")
    m = tmp_path / "map.h5"
    assert run("ingest", rec, "--map", m).exit_code == 0
    with h5py.File(m, "a") as f:  # a map written before sessions had a visit column
        del f["sessions/visit"]
    assert run("info", m).exit_code == 0
    r = run("ingest", rec, "--map", m, "--revisit")
    assert r.exit_code == 0 and "5 frames ingested" in r.output and "visit 2" in r.output
    r = run("info", m, "--format", "json")
    assert [s["visit"] for s in json.loads(r.output)["sessions"]] == [1, 2]

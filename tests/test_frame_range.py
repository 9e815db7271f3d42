"""``ltc ingest --frames START:STOP[:STEP]`` (recordings/open.py): a range of a recording's frames
mapped as its own session. The range by hand, a range mapped as a recording holding only those
frames maps, two ranges as two sessions, resuming only the same range, and the errors."""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from ltc_cli.cli import cli
from ltc_cli.config import defaults
from ltc_cli.errors import ConfigError, RecordingError
from ltc_cli.ingest.frame_setup import frame_setup_for
from ltc_cli.ingest.session import ingest
from ltc_cli.map.store import load_map
from ltc_cli.recordings.open import frame_range, frames_text, open_recording, select_frames
from ltc_cli.validation import validate

LAP1 = Path(__file__).resolve().parent.parent / "sample_data" / "lap1"
N_FRAMES = 76


@pytest.mark.parametrize("text,want,shown", [
    ("0:40", slice(0, 40), "0:40"),
    ("40:", slice(40, None), "40:"),
    (":40", slice(None, 40), ":40"),
    ("::2", slice(None, None, 2), "::2"),
    ("10:50:3", slice(10, 50, 3), "10:50:3"),
    ("10:50:1", slice(10, 50, 1), "10:50"),
    (" 5 : 9 ", slice(5, 9), "5:9"),
])
def test_a_range_by_hand(text, want, shown):
    assert frame_range(text) == want
    assert frames_text(frame_range(text)) == shown
    assert frames_text(None) == ""


@pytest.mark.parametrize("text", ["5", "a:b", "1:2:3:4", "-5:", "0:10:0", "1.5:3", ""])
def test_a_range_that_is_not_one_is_refused(text):
    with pytest.raises(ConfigError, match="--frames"):
        frame_range(text)


def test_the_range_keeps_each_frames_position_and_key():
    rec = open_recording(LAP1)
    part = select_frames(rec, slice(10, 30, 5))
    assert [(f.index, f.key) for f in part.frames] == [(k, rec.frames[k].key) for k in (10, 15, 20, 25)]
    assert part.identity == rec.identity and len(rec.frames) == N_FRAMES
    with pytest.raises(RecordingError, match="selects none of its 76 frames"):
        select_frames(rec, slice(80, None))


def cut(root: Path, keep: range) -> Path:
    """sample_data/lap1 holding only the frames at positions ``keep`` (poses.txt's lines)."""
    rec = root / "cut"
    shutil.copytree(LAP1, rec)
    lines = (LAP1 / "poses.txt").read_text().splitlines()
    (rec / "poses.txt").write_text("\n".join(lines[k] for k in keep) + "\n")
    kept = {lines[k].split()[0] for k in keep}
    for path in [*(rec / "rgb").iterdir(), *(rec / "depth").iterdir(), *(rec / "detections").iterdir()]:
        if path.stem not in kept:
            path.unlink()
    return rec


def test_a_range_maps_as_a_recording_of_those_frames(tmp_path, monkeypatch):
    # Under one set-up: a range takes the whole recording's (the test below), a cut folder its own.
    whole = frame_setup_for(open_recording(LAP1))
    monkeypatch.setattr("ltc_cli.ingest.session.frame_setup_for", lambda rec, warn=None: whole)
    ingest([LAP1], tmp_path / "range.h5", defaults(), frames=slice(20, 60, 2))
    ingest([cut(tmp_path, range(20, 60, 2))], tmp_path / "cut.h5", defaults())
    a, b = load_map(tmp_path / "range.h5"), load_map(tmp_path / "cut.h5")
    for k, v in a.objects.columns().items():
        if k in ("first_frame", "last_frame"):  # positions in the whole recording: frame 20 + 2k is the cut's k
            v = np.where(v >= 0, (v - 20) // 2, v)
        np.testing.assert_array_equal(v, b.objects.columns()[k], err_msg=k)
    # The same events; the range's frames keep their positions in the whole recording (the cut
    # folder's are 0-19), and their keys its identity.
    assert [(e.kind, e.object_id, e.other_id) for e in a.events] == \
        [(e.kind, e.object_id, e.other_id) for e in b.events]
    assert {(e.frame - 20) // 2 for e in a.events if e.frame >= 0} == {e.frame for e in b.events if e.frame >= 0}
    assert a.sessions[0]["frames"] == "20:60:2" and b.sessions[0]["frames"] == ""


def test_two_ranges_are_two_sessions_and_a_run_over_all_is_then_a_no_op(tmp_path):
    m = tmp_path / "m.h5"
    r = CliRunner().invoke(cli, ["ingest", str(LAP1), "--map", str(m), "--frames", "0:40"])
    assert r.exit_code == 0 and "40 frames ingested" in r.output, r.output
    r = CliRunner().invoke(cli, ["ingest", str(LAP1), "--map", str(m), "--frames", "40:"])
    assert r.exit_code == 0 and "36 frames ingested" in r.output, r.output
    r = CliRunner().invoke(cli, ["ingest", str(LAP1), "--map", str(m)])
    assert "0 frames ingested, 0 skipped, 76 already in the map" in r.output
    smap = load_map(m)
    assert [(s["frames"], s["frames_done"], s["visit"]) for s in smap.sessions] == [("0:40", 40, 1), ("40:", 36, 1)]
    whole = tmp_path / "whole.h5"
    ingest([LAP1], whole, defaults())
    assert smap.frame_keys == load_map(whole).frame_keys  # the same keys as one session over all
    info = CliRunner().invoke(cli, ["info", str(m)])
    assert "frames 0:40" in info.output and "frames 40:" in info.output
    r = CliRunner().invoke(cli, ["export", str(m), "--format", "json", "-o", str(tmp_path / "m.json")])
    assert r.exit_code == 0, r.output
    doc = json.loads((tmp_path / "m.json").read_text())
    validate(doc, "export", "m.json")
    assert [s["frames"] for s in doc["map"]["sessions"]] == ["0:40", "40:"]


def test_every_range_is_set_up_as_the_whole_recording(tmp_path):
    """The floor and the depth error (and an estimated up axis) are measured on the whole
    recording's frames, whatever the range: its sessions are in one map frame. Measured on the
    ranges' own frames, lap 1's floor is 0.0005 m in 0:40 and -0.0001 m in 40:, its depth error
    0.00398 and 0.00406 m at 1 m; 0.0 m and 0.00416 m on the whole."""
    m, whole = tmp_path / "m.h5", tmp_path / "whole.h5"
    ingest([LAP1], m, defaults(), frames=slice(0, 40))
    ingest([LAP1], m, defaults(), frames=slice(40, None))
    ingest([LAP1], whole, defaults())
    setup = frame_setup_for(open_recording(LAP1))
    ref = load_map(whole).sessions[0]
    assert json.loads(ref["floor_z"]) == [setup.floor_z]
    assert json.loads(ref["cameras"])[0]["depth_noise"] == setup.depth_noise
    for row in load_map(m).sessions:
        assert [row[k] for k in ("up_rotation", "floor_z", "cameras")] == \
            [ref[k] for k in ("up_rotation", "floor_z", "cameras")], row["frames"]
    # ltc check says so too.
    for spec in ("0:40", "40:", "::3"):
        r = CliRunner().invoke(cli, ["check", str(LAP1), "--frames", spec, "--json"])
        doc = json.loads(r.stdout)
        assert (doc["floor_z"], doc["camera"]["depth_noise"]) == (round(setup.floor_z, 4), setup.depth_noise)


def test_an_interrupted_range_is_resumed_by_the_same_range_only(tmp_path):
    m, asked = tmp_path / "m.h5", []
    s = ingest([LAP1], m, defaults(), frames=slice(0, 40), checkpoint_every=5,
               should_stop=lambda: asked.append(1) or len(asked) > 12)
    assert s.interrupted and s.frames_done == 12
    s = ingest([LAP1], m, defaults(), frames=slice(0, 40))
    assert (s.frames_done, s.frames_already) == (28, 12)
    assert [(r["frames"], r["status"], r["frames_done"]) for r in load_map(m).sessions] == [("0:40", "complete", 40)]
    # Interrupted again in another range: a third range is a session of its own.
    asked.clear()
    ingest([LAP1], m, defaults(), frames=slice(40, 60), should_stop=lambda: asked.append(1) or len(asked) > 5)
    ingest([LAP1], m, defaults(), frames=slice(60, None))
    rows = load_map(m).sessions
    assert [(r["frames"], r["status"]) for r in rows] == [("0:40", "complete"), ("40:60", "interrupted"),
                                                         ("60:", "complete")]


def test_a_bad_range_is_one_line_and_writes_no_map(tmp_path):
    m = tmp_path / "m.h5"
    for spec, message in (("5", "Error: --frames '5': not START:STOP[:STEP]"),
                          ("100:200", f"Error: {LAP1}: --frames 100:200 selects none of its 76 frames")):
        r = CliRunner().invoke(cli, ["ingest", str(LAP1), "--map", str(m), "--frames", spec])
        assert r.exit_code == 1 and r.output.strip().splitlines()[-1].startswith(message), r.output
        assert "Traceback" not in r.output and not m.exists()


def test_check_looks_at_the_range_alone(tmp_path):
    for spec, n in (("0:11", 11), ("::2", 38), ("70:", 6)):
        r = CliRunner().invoke(cli, ["check", str(LAP1), "--frames", spec, "--json"])
        assert r.exit_code == 0, r.output
        assert json.loads(r.stdout)["frames"] == n
    r = CliRunner().invoke(cli, ["check", str(LAP1), "--frames", "76:"])
    assert r.exit_code == 1 and "selects none of its 76 frames" in r.output

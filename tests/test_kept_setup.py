"""A recording the map has read before is set up as it was then (ingest/session_row.kept_setup): its
up rotation, floor height and depth error come from the map's session row, not from a new estimate,
so that its sessions stay in one map frame whatever a later ltc (or another range of it) measures."""

import json
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ltc_cli.config import defaults
from ltc_cli.ingest.frame_setup import FrameSetup, frame_setup_for
from ltc_cli.ingest.session import ingest
from ltc_cli.ingest.session_row import kept_setup
from ltc_cli.map.store import load_map
from ltc_cli.recordings.open import open_recording

LAP1 = Path(__file__).resolve().parent.parent / "sample_data" / "lap1"
# A set-up no estimate of lap 1 gives: levelled 2 degrees about x, the floor 5 cm up, a noisier depth.
OTHER = FrameSetup(Rotation.from_euler("x", 2, degrees=True).as_matrix(), 0.05, 0.006)


def row(**fields) -> dict:
    base = {"sources": json.dumps([str(LAP1.resolve())]), "readers": json.dumps(["ltc-recording/1"]),
            "reader_options": json.dumps([{}]), "up_rotation": json.dumps([np.eye(3).tolist()]),
            "floor_z": json.dumps([0.01]), "cameras": json.dumps([{"width": 320, "depth_noise": 0.004}])}
    return base | fields


def test_the_latest_session_that_read_it_the_same_way_gives_its_setup():
    rec = open_recording(LAP1)
    got = kept_setup(rec, None, {}, [row(floor_z=json.dumps([0.02])), row()])
    np.testing.assert_array_equal(got.R_up, np.eye(3))
    assert (got.floor_z, got.depth_noise) == (0.01, 0.004)
    got = kept_setup(rec, None, {}, [row(floor_z=json.dumps([None]), cameras=json.dumps([{"width": 320}]))])
    assert (got.floor_z, got.depth_noise) == (None, None)
    assert kept_setup(rec, "ltc-recording/1", {}, [row()]).floor_z == 0.01  # the session's reader, named


def test_a_recording_read_another_way_or_new_or_from_an_older_map_is_measured():
    rec = open_recording(LAP1)
    assert kept_setup(rec, None, {"up": "estimate"}, [row()]) is None  # other options now
    assert kept_setup(rec, "drift-6", {}, [row()]) is None  # another reader now (tests/replay.py's)
    assert kept_setup(rec, None, {}, [row(readers=json.dumps(["folder"]))]) is None
    assert kept_setup(rec, None, {}, [row(sources=json.dumps(["/elsewhere"]))]) is None
    assert kept_setup(rec, None, {}, []) is None
    older = row()
    del older["floor_z"], older["cameras"]
    assert kept_setup(rec, None, {}, [older]) is None
    assert kept_setup(rec, None, {}, [row(up_rotation=json.dumps([[1, 0, 0]]))]) is None


def test_a_revisit_and_a_range_keep_the_setup_of_the_first_session(tmp_path, monkeypatch):
    m = tmp_path / "m.h5"
    # The first session as an ltc whose estimate was OTHER set it up.
    monkeypatch.setattr("ltc_cli.ingest.session.frame_setup_for", lambda rec, warn=None: OTHER)
    ingest([LAP1], m, defaults(), frames=slice(0, 40))
    monkeypatch.undo()
    ingest([LAP1], m, defaults(), frames=slice(40, None))
    ingest([LAP1], m, defaults(), revisit=True)
    rows = load_map(m).sessions
    assert len(rows) == 3
    for r in rows:
        np.testing.assert_allclose(json.loads(r["up_rotation"])[0], OTHER.R_up, atol=1e-9)
        assert json.loads(r["floor_z"]) == [0.05]
        assert json.loads(r["cameras"])[0]["depth_noise"] == 0.006
    # A map of its own measures it anew.
    ingest([LAP1], tmp_path / "new.h5", defaults())
    fresh = load_map(tmp_path / "new.h5").sessions[0]
    assert json.loads(fresh["floor_z"]) == [frame_setup_for(open_recording(LAP1)).floor_z] != [0.05]

"""Bad values inside a recording's files (issue 10, item 7): a NaN detection score, a class the
recording's class list does not hold, an all-zero depth image and a 16-bit PNG given as the colour
image. Each is one line on stderr naming the file; an unusable frame is skipped (exit 0, counted),
and ``--strict`` makes each an error (exit 1); a skipped frame never changes the map."""

import hashlib
import json

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from ltc_cli.cli import cli
from ltc_cli.map.store import load_map
from tests.recording import write_recording


def ingest(*args):
    r = CliRunner().invoke(cli, ["ingest", *map(str, args)])
    return r, [ln for ln in r.stderr.splitlines() if ln.strip()]


def sha256(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def lap1(tmp_path_factory):
    return write_recording(tmp_path_factory.mktemp("lap1") / "lap1")


def nan_score(rec):
    path = rec / "detections" / "000000.json"
    doc = json.loads(path.read_text())
    doc["instances"][0]["score"] = float("nan")
    path.write_text(json.dumps(doc))  # json writes NaN, and json.loads reads it back
    assert "NaN" in path.read_text()
    return path


def zero_depth(rec):
    path = rec / "depth" / "000000.png"
    shape = np.asarray(Image.open(path)).shape
    Image.fromarray(np.zeros(shape, np.uint16)).save(path)
    return path


def depth_as_colour(rec):
    path = rec / "rgb" / "000000.png"
    path.write_bytes((rec / "depth" / "000000.png").read_bytes())  # a 16-bit single-channel PNG
    assert Image.open(path).mode.startswith("I")
    return path


@pytest.mark.parametrize("corrupt", [nan_score, zero_depth, depth_as_colour], ids=lambda f: f.__name__)
def test_unusable_frame_is_skipped_with_one_line_naming_the_file(lap1, tmp_path, corrupt):
    m = tmp_path / "map.h5"
    assert ingest(lap1, "--map", m)[0].exit_code == 0
    before = sha256(m)
    bad = write_recording(tmp_path / "bad", cam_ys=(0.0,))
    culprit = corrupt(bad)

    r, lines = ingest(bad, "--map", m)
    # Its only frame was bad: nothing mapped, so the run fails (issue 10 item 8) after the warning.
    assert r.exit_code == 1, r.output
    assert len(lines) == 2 and lines[0].startswith("warning: skipped frame 000000"), lines
    assert "no frame could be mapped" in lines[1]
    assert str(culprit) in lines[0]
    assert "1 skipped" in r.stdout
    assert sha256(m) == before

    r, lines = ingest(bad, "--map", m, "--strict")
    assert r.exit_code == 1
    assert len(lines) == 1 and str(culprit) in lines[0] and "Traceback" not in r.output
    assert sha256(m) == before


def add_lamps(rec, keys):
    """A 'lamp' instance (not in recording.yaml's classes) in the detections of each frame of
    ``keys``, with the mask of the frame's first instance so it would land on a real object."""
    for key in keys:
        path = rec / "detections" / f"{key}.json"
        doc = json.loads(path.read_text())
        doc["instances"].append({"class": "lamp", "score": 0.8, "mask": doc["instances"][0]["mask"]})
        path.write_text(json.dumps(doc))


def objects_of(path):
    t = load_map(path).objects
    return {k: v for k, v in t.columns().items()}


def test_class_not_in_the_class_list_warns_once_per_recording(tmp_path):
    clean = write_recording(tmp_path / "clean")
    lamps = write_recording(tmp_path / "lamps")
    add_lamps(lamps, ["000001", "000002", "000003"])
    m_clean, m_lamps = tmp_path / "clean.h5", tmp_path / "lamps.h5"
    assert ingest(clean, "--map", m_clean)[0].exit_code == 0

    r, lines = ingest(lamps, "--map", m_lamps)
    assert r.exit_code == 0, r.output
    # Three frames name the lamp, one line says so: the first file that does.
    first = lamps / "detections" / "000001.json"
    assert lines == [f"warning: {first}: class 'lamp' is not in the recording's class list: its scores are ignored"]
    assert "5 frames ingested" in r.stdout
    # The lamp's scores are dropped and nothing else changes: the same objects as without them.
    got, want = objects_of(m_lamps), objects_of(m_clean)
    assert sorted(got) == sorted(want)
    for k in want:
        np.testing.assert_array_equal(got[k], want[k], err_msg=k)


def test_class_not_in_the_class_list_is_an_error_with_strict(lap1, tmp_path):
    m = tmp_path / "map.h5"
    assert ingest(lap1, "--map", m)[0].exit_code == 0
    before = sha256(m)
    bad = write_recording(tmp_path / "bad", cam_ys=(0.0, 0.75))
    add_lamps(bad, ["000000"])
    r, lines = ingest(bad, "--map", m, "--strict")
    assert r.exit_code == 1
    culprit = bad / "detections" / "000000.json"
    assert len(lines) == 1 and str(culprit) in lines[0] and "'lamp'" in lines[0], lines
    assert sha256(m) == before


def test_a_newer_recording_format_says_which_version_ltc_reads(tmp_path):
    rec = write_recording(tmp_path / "rec", cam_ys=(0.0,))
    meta = rec / "recording.yaml"
    meta.write_text(meta.read_text().replace("ltc-recording/1", "ltc-recording/2"))
    r, lines = ingest(rec, "--map", tmp_path / "m.h5")
    assert r.exit_code == 1 and len(lines) == 1
    assert "ltc-recording/2" in lines[0] and "reads ltc-recording/1" in lines[0] and str(meta) in lines[0]
    assert not (tmp_path / "m.h5").exists()

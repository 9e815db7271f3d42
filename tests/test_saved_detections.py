"""``detector.save_to`` (ltc_cli/recordings/saved_detections.py): an ingest writes each detected
frame's detections as the recorded detector reads them, and replaying them makes the same map."""

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from ltc_cli.cli import cli
from ltc_cli.config import defaults, load_config
from ltc_cli.ingest.session import ingest
from ltc_cli.map.store import load_map
from ltc_cli.recordings import rle
from ltc_cli.recordings.saved_detections import detections_doc
from ltc_cli.types import Detection
from tests.shared_data import SHARED
from tests.test_revisit import assert_same_map

LAP1 = Path(__file__).resolve().parent.parent / "sample_data" / "lap1"
DINING = SHARED / "data" / "dining-room"
MODEL = SHARED / "models" / "yolov8n-seg_fp32.onnx"


def test_a_frames_document_by_hand():
    mask = np.zeros((4, 5), bool)
    mask[1:3, 2:5] = True
    dets = [Detection(mask, np.array([0.1, 0.7, 0.0])), Detection(~mask, np.array([0.0, 0.0, 0.25]))]
    doc = detections_doc("000007", "some-model", dets, ["cup", "chair", "tv"])
    assert doc["frame"] == "000007" and doc["detector"] == "some-model"
    a, b = doc["instances"]
    assert (a["class"], a["score"], a["scores"]) == ("chair", 0.7, {"cup": 0.1, "chair": 0.7})
    assert (b["class"], b["score"], b["scores"]) == ("tv", 0.25, {"tv": 0.25})
    np.testing.assert_array_equal(rle.decode(a["mask"]), mask)
    np.testing.assert_array_equal(rle.decode(b["mask"]), ~mask)
    assert json.loads(json.dumps(doc)) == doc  # plain JSON, floats exact


@pytest.mark.parametrize("jobs", [1, 2])
def test_the_sample_laps_detections_saved_and_replayed_make_its_map(tmp_path, jobs):
    saved = tmp_path / "saved"
    cfg = load_config(None, [f"detector.save_to={saved}"])
    a = ingest([LAP1], tmp_path / "a.h5", cfg, jobs=jobs)  # with 2, the look-ahead's threads write
    files = sorted(p.stem for p in saved.glob("*.json") if p.name != "classes.json")
    assert files == sorted(line.split()[0] for line in (LAP1 / "poses.txt").read_text().splitlines())
    assert json.loads((saved / "classes.json").read_text())["classes"] == load_map(tmp_path / "a.h5").classes
    b = ingest([LAP1], tmp_path / "b.h5", load_config(None, [f"detector.options.folder={saved}"]))
    assert (a.frames_done, a.detections, a.created, a.merged, a.removed) == \
        (b.frames_done, b.detections, b.created, b.merged, b.removed)
    assert_same_map(tmp_path / "a.h5", tmp_path / "b.h5")


@pytest.mark.skipif(not (DINING.is_dir() and MODEL.is_file()), reason="needs ../shared (dining room, fp32 model)")
def test_a_models_detections_replayed_make_the_models_map(tmp_path):
    """The real model on the real dining room: the replay's map is the model's, to the bit, with the
    model's 80 classes in its order (classes.json), though the frames name only a few of them."""
    runner = CliRunner()
    common = ["-r", "intrinsics=518,519,325.5,253.5"]
    r = runner.invoke(cli, ["ingest", str(DINING), "--map", str(tmp_path / "model.h5"), *common,
                            "--detector", "onnx-yolo-seg", "--set", f"detector.options.model={MODEL}",
                            "--set", f"detector.save_to={tmp_path / 'dets'}"])
    assert r.exit_code == 0, r.output
    r = runner.invoke(cli, ["ingest", str(DINING), "--map", str(tmp_path / "replay.h5"), *common,
                            "--set", f"detector.options.folder={tmp_path / 'dets'}"])
    assert r.exit_code == 0, r.output
    assert_same_map(tmp_path / "model.h5", tmp_path / "replay.h5")
    classes = load_map(tmp_path / "replay.h5").classes
    assert len(classes) == 80 and classes == load_map(tmp_path / "model.h5").classes


def test_bad_save_to_and_class_files_are_one_line(tmp_path):
    runner = CliRunner()
    blocker = tmp_path / "a-file"
    blocker.write_text("x")
    r = runner.invoke(cli, ["ingest", str(LAP1), "--map", str(tmp_path / "m.h5"), "--set",
                            f"detector.save_to={blocker / 'dets'}"])
    assert r.exit_code == 1 and r.stderr.startswith(f"Error: {blocker / 'dets'}: detector.save_to: cannot write there")
    assert len(r.stderr.strip().splitlines()) == 1 and not (tmp_path / "m.h5").exists()
    r = runner.invoke(cli, ["ingest", str(LAP1), str(LAP1.parent / "lap2"), "--map", str(tmp_path / "m.h5"),
                            "--set", f"detector.save_to={tmp_path / 'dets'}"])
    assert r.exit_code == 1 and "detector.save_to takes one recording per folder" in r.stderr
    assert "put {recording} in it" in r.stderr
    assert not (tmp_path / "m.h5").exists()
    # One folder for two recordings (two laps of ingest-many with one save_to): the second is refused
    # before it writes a file, and the first one's files are as they were; the first again is fine.
    dets = tmp_path / "dets"
    assert runner.invoke(cli, ["ingest", str(LAP1), "--map", str(tmp_path / "a.h5"), "--set",
                               f"detector.save_to={dets}"]).exit_code == 0
    before = {p.name: p.read_bytes() for p in dets.iterdir()}
    r = runner.invoke(cli, ["ingest", str(LAP1.parent / "lap2"), "--map", str(tmp_path / "b.h5"), "--set",
                            f"detector.save_to={dets}"])
    assert r.exit_code == 1 and len(r.stderr.strip().splitlines()) == 1
    assert "detector.save_to: this folder holds another recording's detections" in r.stderr
    assert {p.name: p.read_bytes() for p in dets.iterdir()} == before and not (tmp_path / "b.h5").exists()
    r = runner.invoke(cli, ["ingest", str(LAP1), "--map", str(tmp_path / "a2.h5"), "--set", f"detector.save_to={dets}"])
    assert r.exit_code == 0, r.output
    saved = tmp_path / "saved"
    saved.mkdir()
    (saved / "classes.json").write_text('{"classes": ["chair", "chair"]}')
    r = runner.invoke(cli, ["ingest", str(LAP1), "--map", str(tmp_path / "m.h5"), "--set",
                            f"detector.options.folder={saved}"])
    assert r.exit_code == 1 and r.stderr.strip() == (
        f"Error: {saved / 'classes.json'}: not a class list written by detector.save_to (classes: distinct names)")


def test_frames_detected_on_dask_workers_are_saved_too(tmp_path):
    distributed = pytest.importorskip("distributed")
    from ltc_cli.ingest.cluster import Cluster

    saved = tmp_path / "saved"
    local = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=":0")
    with Cluster(distributed.Client(local), local) as cluster:
        ingest([LAP1], tmp_path / "dask.h5", load_config(None, [f"detector.save_to={saved}"]), cluster=cluster)
    ingest([LAP1], tmp_path / "one.h5", defaults())
    assert len([p for p in saved.glob("*.json") if p.name != "classes.json"]) == 76
    ingest([LAP1], tmp_path / "replay.h5", load_config(None, [f"detector.options.folder={saved}"]))
    assert_same_map(tmp_path / "one.h5", tmp_path / "replay.h5")


def test_recording_in_the_folder_names_each_recordings_own(tmp_path):
    """Two recordings in one ingest, each saved to its own folder by ``{recording}``, and replayed
    from the same pattern: the two sessions' map again."""
    lap2 = LAP1.parent / "lap2"
    runner = CliRunner()
    r = runner.invoke(cli, ["ingest", str(LAP1), str(lap2), "--map", str(tmp_path / "a.h5"),
                            "--set", f"detector.save_to={tmp_path / 'dets' / '{recording}'}"])
    assert r.exit_code == 0, r.output
    for lap in (LAP1, lap2):
        names = {p.name for p in (tmp_path / "dets" / lap.name).iterdir()}
        assert names == {p.name for p in (lap / "detections").iterdir()} | {"classes.json"}
    r = runner.invoke(cli, ["ingest", str(LAP1), str(lap2), "--map", str(tmp_path / "b.h5"),
                            "--set", f"detector.options.folder={tmp_path / 'dets' / '{recording}'}"])
    assert r.exit_code == 0, r.output
    assert_same_map(tmp_path / "a.h5", tmp_path / "b.h5")

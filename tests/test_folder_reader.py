"""The plain-folder reader (plugins/readers/folder.py): colour and depth images and a pose file, the
camera given on the command line. The real dining-room folder of ../shared maps with one command and
gives the same map as the hand-written ltc-recording/1 route of test_dining_room.py; a simulated lap
laid out as a plain folder gives the same objects as the lap itself."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from ltc_cli.cli import cli
from ltc_cli.errors import ConfigError, FrameError, RecordingError
from ltc_cli.geometry.camera import pose_matrix
from ltc_cli.map.model import ACTIVE
from ltc_cli.map.store import load_map
from ltc_cli.recordings.open import open_recording
from ltc_plugins.readers.folder import FolderReader
from tests.shared_data import SHARED

ROOT = Path(__file__).resolve().parents[1]
LAP1 = ROOT / "sample_data" / "lap1"
DINING = SHARED / "data" / "dining-room"
MODEL = SHARED / "models" / "yolov8n-seg_int8.onnx"
W, H = 8, 6


def write_folder(root: Path, stems, pose_lines, depth_ext=".pgm") -> Path:
    for i, stem in enumerate(stems):
        (root / "color").mkdir(parents=True, exist_ok=True)
        (root / "depth").mkdir(exist_ok=True)
        Image.fromarray(np.full((H, W, 3), 10 * i, np.uint8)).save(root / "color" / f"{stem}.png")
        Image.fromarray(np.full((H, W), 1000 + i, np.uint16)).save(root / "depth" / f"{stem}{depth_ext}")
    (root / "pose.txt").write_text("".join(line + "\n" for line in pose_lines))
    return root


def test_plain_folder_frames_poses_depth_and_camera(tmp_path):
    # Natural order: "2" before "10". Line N is the N-th image.
    poses = ["1 2 3 0 0 0 1", "0 0 0 0 0 0.7071067811865476 0.7071067811865476", "-1 0 0.5 1 0 0 0"]
    root = write_folder(tmp_path / "rec", ["10", "2", "1"], poses)
    assert FolderReader().sniff(root)
    rec = open_recording(root, None, {"intrinsics": "5,6,3.5,2.5"})  # chosen by sniffing
    assert rec.format == "folder" and [f.key for f in rec.frames] == ["1", "2", "10"]
    assert (rec.intrinsics.fx, rec.intrinsics.fy, rec.intrinsics.cx, rec.intrinsics.cy) == (5, 6, 3.5, 2.5)
    assert (rec.intrinsics.width, rec.intrinsics.height) == (W, H)
    assert rec.up == "estimate"  # the default: SLAM worlds start at the first camera
    f = rec.frames[1].load()  # frame "2", the second line: a quarter turn about z
    assert f.depth_m[0, 0] == pytest.approx(1.001)  # millimetres by default (value 1000 + 1)
    np.testing.assert_allclose(f.T_world_camera, [[0, -1, 0, 0], [1, 0, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], atol=1e-12)
    np.testing.assert_allclose(rec.frames[2].load().T_world_camera[:3, 3], [-1, 0, 0.5])
    # Another depth unit and a known up.
    rec2 = FolderReader().open(root, {"intrinsics": [5, 6, 3.5, 2.5], "depth_scale": 5000, "up": "z"})
    assert rec2.frames[0].load().depth_m[0, 0] == pytest.approx(1002 / 5000) and rec2.up is None  # "1": 1000 + 2
    assert rec2.identity != rec.identity  # another camera is another recording


def test_named_pose_lines_and_matrices(tmp_path):
    T = pose_matrix([1.0, 2.0, 3.0], [0.0, 0.0, 0.0, 1.0])
    root = write_folder(tmp_path / "a", ["000001", "000002"], ["2 0 0 0 0 0 0 1", "1 1 2 3 0 0 0 1"])
    rec = FolderReader().open(root, {"intrinsics": "5,6,3,2"})
    np.testing.assert_allclose(rec.frames[0].load().T_world_camera, T)  # "1" names 000001
    np.testing.assert_allclose(rec.frames[1].load().T_world_camera[:3, 3], [0, 0, 0])
    kitti = " ".join(str(v) for v in T[:3].ravel())
    root = write_folder(tmp_path / "b", ["a"], [kitti], depth_ext=".png")
    np.testing.assert_allclose(FolderReader().open(root, {"intrinsics": "5,6,3,2"}).frames[0].load().T_world_camera, T)


def log_text(Ts) -> str:
    """Open3D's trajectory.log of the camera-to-world matrices Ts, as Open3D writes it
    (WritePinholeCameraTrajectoryToLOG: "i i i+1", then the rows with 8 decimals)."""
    return "".join(f"{k} {k} {k + 1}\n" + "".join(" ".join(f"{v:.8f}" for v in row) + "\n" for row in T)
                   for k, T in enumerate(Ts))


def test_open3d_trajectory_log(tmp_path):
    # Frame "2": a quarter turn about z at (1, 2, 3); frame "10": none, at the origin.
    T2 = np.array([[0.0, -1, 0, 1], [1, 0, 0, 2], [0, 0, 1, 3], [0, 0, 0, 1]])
    root = write_folder(tmp_path / "rec", ["10", "2"], [])
    (root / "pose.txt").unlink()
    (root / "trajectory.log").write_text(log_text([T2, np.eye(4)]))
    assert FolderReader().sniff(root)
    rec = FolderReader().open(root, {"intrinsics": "5,6,3,2"})
    assert [f.key for f in rec.frames] == ["2", "10"] and rec.meta["poses"] == "trajectory.log"
    np.testing.assert_array_equal(rec.frames[0].load().T_world_camera, T2)
    np.testing.assert_array_equal(rec.frames[1].load().T_world_camera, np.eye(4))
    (root / "trajectory.log").write_text(log_text([T2]) + "1 1 2\n1 0 0 0\n")
    with pytest.raises(RecordingError, match="three numbers, then four lines of four"):
        FolderReader().open(root, {"intrinsics": "5,6,3,2"})
    scaled = T2.copy()
    scaled[:3, :3] *= 2
    (root / "trajectory.log").write_text(log_text([scaled, np.eye(4)]))
    with pytest.raises(FrameError, match="not a rotation"):
        FolderReader().open(root, {"intrinsics": "5,6,3,2"}).frames[0].load()


def test_open3d_reconstruction_folder_needs_no_options(tmp_path):
    """Open3D's reconstruction system keeps color/, depth/, camera_intrinsic.json (its
    PinholeCameraIntrinsic: intrinsic_matrix column by column) and writes scene/trajectory.log."""
    root = write_folder(tmp_path / "rec", ["000000", "000001"], [])
    (root / "pose.txt").unlink()
    (root / "scene").mkdir()
    T1 = pose_matrix([0.5, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0])
    (root / "scene" / "trajectory.log").write_text(log_text([np.eye(4), T1]))
    K = {"width": W, "height": H, "intrinsic_matrix": [500.0, 0, 0, 0, 501.0, 0, 4.5, 3.5, 1]}
    (root / "camera_intrinsic.json").write_text(json.dumps(K))
    assert FolderReader().sniff(root)
    rec = open_recording(root)
    i = rec.intrinsics
    assert (i.width, i.height, i.fx, i.fy, i.cx, i.cy) == (W, H, 500.0, 501.0, 4.5, 3.5)
    np.testing.assert_array_equal(rec.frames[1].load().T_world_camera, T1)
    assert FolderReader().open(root, {"intrinsics": "5,6,3,2"}).intrinsics.fx == 5  # the option wins
    (root / "camera_intrinsic.json").write_text(json.dumps({**K, "width": 640}))
    with pytest.raises(RecordingError, match="the camera is 640x6, the depth images 8x6"):
        open_recording(root)
    (root / "camera_intrinsic.json").write_text(json.dumps({**K, "intrinsic_matrix": [500.0, 0, 0]}))
    with pytest.raises(RecordingError, match="not an Open3D camera intrinsic file"):
        open_recording(root)


def test_replica_layout_by_patterns_and_numbers(tmp_path):
    """Replica as NICE-SLAM distributes it: results/frame%06d.jpg and results/depth%06d.png in one
    folder, traj.txt with a 4x4 camera-to-world matrix per line."""
    res = tmp_path / "room0" / "results"
    res.mkdir(parents=True)
    for i in (0, 1, 12):
        Image.fromarray(np.full((H, W, 3), 10 * i, np.uint8)).save(res / f"frame{i:06d}.jpg")
        Image.fromarray(np.full((H, W), 6553 + i, np.uint16)).save(res / f"depth{i:06d}.png")
    T = [np.eye(4), pose_matrix([1.0, 2.0, 3.0], [0.0, 0.0, 0.0, 1.0]), np.eye(4)]
    T[2][:3, 3] = [0.0, 0.0, -1.0]
    (tmp_path / "room0" / "traj.txt").write_text("".join(" ".join(f"{v:.8f}" for v in M.ravel()) + "\n" for M in T))
    opts = {"intrinsics": "600,600,599.5,339.5", "color": "results/frame*.jpg", "depth": "results/depth*.png",
            "poses": "traj.txt", "depth_scale": 6553.5}
    rec = FolderReader().open(tmp_path / "room0", opts)
    assert [f.key for f in rec.frames] == ["frame000000", "frame000001", "frame000012"]
    f = rec.frames[2].load()  # frame 12 pairs with depth 12 (6553 + 12), the third pose line
    assert f.depth_m[0, 0] == pytest.approx(6565 / 6553.5)
    np.testing.assert_allclose(f.T_world_camera[:3, 3], [0.0, 0.0, -1.0])
    np.testing.assert_allclose(rec.frames[1].load().T_world_camera[:3, 3], [1.0, 2.0, 3.0])
    # Two depth images of one number cannot be paired by it.
    Image.fromarray(np.full((H, W), 1, np.uint16)).save(res / "depth_1.png")
    with pytest.raises(RecordingError, match="two depth images are numbered 1"):
        FolderReader().open(tmp_path / "room0", opts)
    assert len(FolderReader().open(tmp_path / "room0", {**opts, "depth": "results/depth0*.png"}).frames) == 3


def test_plain_folder_errors(tmp_path):
    root = write_folder(tmp_path / "rec", ["1", "2"], ["0 0 0 0 0 0 1"])
    with pytest.raises(RecordingError, match="intrinsics=FX,FY,CX,CY"):
        FolderReader().open(root, {})
    with pytest.raises(RecordingError, match="1 pose lines for 2 colour images"):
        FolderReader().open(root, {"intrinsics": "5,6,3,2"})
    with pytest.raises(ConfigError, match="intrinsics"):
        FolderReader().open(root, {"intrinsics": "5,6,3"})
    (root / "pose.txt").write_text("1 0 0 0 0 0 0 1\n3 0 0 0 0 0 0 1\n")
    with pytest.raises(RecordingError, match="line 2: no colour image is named '3'"):
        FolderReader().open(root, {"intrinsics": "5,6,3,2"})
    (root / "pose.txt").write_text("1 0 0 0 0 0 0 1\n")
    rec = FolderReader().open(root, {"intrinsics": "5,6,3,2"})
    with pytest.raises(FrameError, match="frame '2' has no pose line"):
        rec.frames[1].load()
    (root / "recording.yaml").write_text("format: ltc-recording/1\n")
    assert not FolderReader().sniff(root)  # a folder with its own layout file is not a plain one


def objects_of(map_path):
    smap = load_map(map_path)
    t = smap.objects
    rows = np.flatnonzero(t.status == ACTIVE)
    return [(smap.classes[int(t.scores[r, :-1].argmax())], t.center[r], t.size[r], t.yaw[r]) for r in rows]


def assert_same_objects(a, b, tol=1e-3):
    assert len(a) == len(b) and len(a) > 0
    for (ca, pa, sa, ya), (cb, pb, sb, yb) in zip(a, b):
        assert ca == cb
        np.testing.assert_allclose(pa, pb, atol=tol)
        np.testing.assert_allclose(sa, sb, atol=tol)
        assert abs(ya - yb) < 1e-3


@pytest.mark.parametrize("pose_file", ["pose.txt", "trajectory.log", "traj.txt"])
def test_simulated_lap_as_a_plain_folder_maps_like_the_lap(tmp_path, pose_file):
    root = tmp_path / "plain"
    root.mkdir()
    dets = LAP1 / "detections"
    import yaml
    meta = yaml.safe_load((LAP1 / "recording.yaml").read_text())
    cam = meta["camera"]
    if pose_file == "traj.txt":  # Replica as NICE-SLAM has it: results/frame*.jpg, depth*.png, the camera above
        (root / "results").mkdir()
        dets = tmp_path / "dets"  # the recorded detections under the frames' names
        dets.mkdir()
        for sub, name, folder in (("rgb", "frame{}.jpg", root / "results"), ("depth", "depth{}.png", root / "results"),
                                  ("detections", "frame{}.json", dets)):
            for p in (LAP1 / sub).iterdir():
                (folder / name.format(p.stem)).symlink_to(p)  # a PNG read as the .jpg: only its name differs
        (tmp_path / "cam_params.json").write_text(json.dumps({"camera": {
            "w": cam["width"], "h": cam["height"], "fx": cam["fx"], "fy": cam["fy"], "cx": cam["cx"], "cy": cam["cy"],
            "scale": meta["depth"]["scale"]}}))
    else:
        (root / "color").symlink_to(LAP1 / "rgb")
        (root / "depth").symlink_to(LAP1 / "depth")
    lines = [ln.split(None, 1)[1] for ln in (LAP1 / "poses.txt").read_text().splitlines() if ln.strip()]
    if pose_file == "pose.txt":  # without frame ids, as many tools write it
        (root / "pose.txt").write_text("\n".join(lines) + "\n")
    else:  # the same poses as matrices made by scipy: Open3D's log, or Replica's row-major lines
        from scipy.spatial.transform import Rotation

        Ts = []
        for line in lines:
            v = np.array(line.split(), dtype=float)
            T = np.eye(4)
            T[:3, :3], T[:3, 3] = Rotation.from_quat(v[3:]).as_matrix(), v[:3]
            Ts.append(T)
        (root / pose_file).write_text(log_text(Ts) if pose_file == "trajectory.log" else
                                      "".join(" ".join(f"{v:.8f}" for v in T.ravel()) + "\n" for T in Ts))
    classes = "[" + ", ".join(meta["classes"]) + "]"
    camera = [] if pose_file == "traj.txt" else ["-r", f"intrinsics={cam['fx']},{cam['fy']},{cam['cx']},{cam['cy']}"]
    runner = CliRunner()
    r = runner.invoke(cli, ["ingest", str(LAP1), "--map", str(tmp_path / "lap.h5")])
    assert r.exit_code == 0, r.output
    r = runner.invoke(cli, ["ingest", str(root), "--map", str(tmp_path / "plain.h5"),
                            *camera, "-r", "up=z", "--set", f"detector.options.folder={dets}",
                            "-r", f"classes={classes}"])
    assert r.exit_code == 0, r.output
    readers = json.loads(load_map(tmp_path / "plain.h5").sessions[0]["readers"])
    assert readers == ["replica" if pose_file == "traj.txt" else "folder"]  # Replica's camera from cam_params.json
    got, want = objects_of(tmp_path / "plain.h5"), objects_of(tmp_path / "lap.h5")
    if pose_file != "pose.txt":
        # The matrices' rotations are re-orthonormalised (1e-16 from the quaternions'): a nearly
        # square footprint may then come out a quarter turn round, the same box.
        got = [(c, p, *quarter_turned(s, y, ref_yaw)) for (c, p, s, y), (_, _, _, ref_yaw) in zip(got, want)]
    assert_same_objects(got, want, tol=1e-9 if pose_file == "pose.txt" else 1e-6)


def quarter_turned(size, yaw, ref_yaw) -> tuple:
    """(size, yaw) of a box re-expressed with the quarter turn nearest ``ref_yaw``."""
    k = int(np.round((yaw - ref_yaw) / (np.pi / 2)))
    return (size[[1, 0, 2]] if k % 2 else size), yaw - k * np.pi / 2


@pytest.mark.skipif(not (DINING.is_dir() and MODEL.is_file()), reason="../shared data or model absent")
def test_dining_room_maps_with_one_command(tmp_path, monkeypatch):
    """The folder as it is in ../shared (color/N.png, depth/N.pgm, pose.txt without frame ids, the
    camera only in its README): one command, no file written by hand, the same map as the
    ltc-recording/1 route of test_dining_room.py."""
    import tests.test_dining_room as hand_written

    monkeypatch.setattr(hand_written, "DATA", DINING)  # found through tests/shared_data.py
    model = f"detector.options.model={MODEL}"
    runner = CliRunner()
    r = runner.invoke(cli, ["ingest", str(DINING), "--map", str(tmp_path / "one.h5"), "--detector", "onnx-yolo-seg",
                            "--set", model, "-r", "intrinsics=518.0,519.0,325.5,253.5"])
    assert r.exit_code == 0, r.output
    assert "5 frames ingested, 0 skipped" in r.output
    rec = hand_written.make_recording(tmp_path / "rec")
    r = runner.invoke(cli, ["ingest", str(rec), "--map", str(tmp_path / "yaml.h5"), "--detector", "onnx-yolo-seg",
                            "--set", model])
    assert r.exit_code == 0, r.output
    one = objects_of(tmp_path / "one.h5")
    assert_same_objects(one, objects_of(tmp_path / "yaml.h5"))
    assert sum(c == "couch" for c, *_ in one) == 1 and sum(c == "dining table" for c, *_ in one) == 1


def test_render_reads_a_recording_as_its_ingest_did(tmp_path):
    """A plain folder ingested with -r options is drawn into with `ltc render --recording` and no
    option: the map's session row keeps the reader and its options. An option given overrides the
    kept one; a map whose row keeps none (made before ltc kept them) needs them as before."""
    from ltc_cli.map.store import save_map

    root = tmp_path / "plain"
    root.mkdir()
    (root / "color").symlink_to(LAP1 / "rgb")
    (root / "depth").symlink_to(LAP1 / "depth")
    lines = [ln.split(None, 1)[1] for ln in (LAP1 / "poses.txt").read_text().splitlines() if ln.strip()]
    (root / "pose.txt").write_text("\n".join(lines) + "\n")
    import yaml
    meta = yaml.safe_load((LAP1 / "recording.yaml").read_text())
    cam = meta["camera"]
    opts = ["-r", f"intrinsics={cam['fx']},{cam['fy']},{cam['cx']},{cam['cy']}", "-r", "up=z",
            "-r", "classes=[" + ", ".join(meta["classes"]) + "]"]
    runner = CliRunner()
    m = tmp_path / "m.h5"
    r = runner.invoke(cli, ["ingest", str(root), "--map", str(m), *opts,
                            "--set", f"detector.options.folder={LAP1 / 'detections'}"])
    assert r.exit_code == 0, r.output
    row = load_map(m).sessions[0]
    kept_options = {"intrinsics": f"{cam['fx']},{cam['fy']},{cam['cx']},{cam['cy']}", "up": "z", "classes": meta["classes"]}
    assert json.loads(row["reader_options"]) == [kept_options]
    ids_first = sorted(int(i) for i in load_map(m).active_rows())
    info = runner.invoke(cli, ["info", str(m)])
    assert (f"     read with -r classes={json.dumps(meta['classes'])} -r intrinsics={cam['fx']},{cam['fy']},{cam['cx']},"
            f"{cam['cy']} -r up=z") in info.output
    doc = json.loads(runner.invoke(cli, ["info", str(m), "--format", "json"]).output)
    assert (doc["sessions"][0]["readers"], doc["sessions"][0]["reader_options"]) == (["folder"], [kept_options])

    def render(name, *extra):
        out = tmp_path / name
        res = runner.invoke(cli, ["render", str(m), "-o", str(out), "--recording", str(root), "--frames", "5,40",
                                  *extra])
        return res, out

    r_kept, kept = render("kept.png")
    assert r_kept.exit_code == 0, r_kept.output
    r_given, given = render("given.png", *opts)
    assert r_given.exit_code == 0, r_given.output
    assert np.array_equal(np.asarray(Image.open(kept)), np.asarray(Image.open(given)))
    r_other, other = render("other.png", "-r", f"intrinsics={cam['fx'] * 2},{cam['fy'] * 2},{cam['cx']},{cam['cy']}")
    assert r_other.exit_code == 0, r_other.output
    assert not np.array_equal(np.asarray(Image.open(kept)), np.asarray(Image.open(other)))
    # A revisit with no option reads the folder as the first visit did: the same objects, same ids.
    r = runner.invoke(cli, ["ingest", str(root), "--map", str(m), "--revisit",
                            "--set", f"detector.options.folder={LAP1 / 'detections'}"])
    assert r.exit_code == 0, r.output
    assert "76 frames ingested" in r.output and "visit 2" in r.output
    smap = load_map(m)
    assert json.loads(smap.sessions[1]["reader_options"]) == [kept_options]
    assert sorted(int(i) for i in smap.active_rows()) == ids_first
    # Another path to other images is not the recording the map read: it needs its options.
    other = tmp_path / "other"
    shutil.copytree(root, other, symlinks=True)
    r = runner.invoke(cli, ["ingest", str(other), "--map", str(m)])
    assert r.exit_code == 1 and "needs the camera: give the reader option intrinsics" in r.output
    smap.sessions[0]["reader_options"] = smap.sessions[1]["reader_options"] = ""  # as a map made before the column
    save_map(smap, m)
    r_old, _ = render("old.png")
    assert r_old.exit_code == 1 and "needs the camera: give the reader option intrinsics" in r_old.output


def test_as_ingested_takes_the_latest_session_that_read_the_recording(tmp_path):
    from ltc_cli.recordings.open import as_ingested

    a, b, c = (tmp_path / n for n in "abc")

    def row(sources, readers, options):
        return {"sources": json.dumps([str(p.resolve()) for p in sources]), "readers": json.dumps(readers),
                "reader_options": options if isinstance(options, str) else json.dumps(options)}

    rows = [row([a, b], ["folder", "tum"], [{"x": 1}, {"y": 2}]), row([a], ["folder"], [{"x": 3}]),
            {"sources": "not json"}]
    assert as_ingested(a, rows) == ("folder", {"x": 3})  # the latest session that read it
    assert as_ingested(b, rows) == ("tum", {"y": 2})  # its own options, by its place in the row
    assert as_ingested(a, rows, options={"z": 1}) == ("folder", {"x": 3, "z": 1})
    assert as_ingested(a, rows, options={"x": 4}) == ("folder", {"x": 4})  # given wins
    assert as_ingested(a, rows, reader="tum", options={"z": 1}) == ("tum", {"z": 1})  # another reader's options
    assert as_ingested(a, rows, reader="folder") == ("folder", {"x": 3})
    assert as_ingested(c, rows, options={"z": 1}) == (None, {"z": 1})  # never read
    old = [row([a], ["folder"], "")]  # a map made before the options were kept
    assert as_ingested(a, old) == ("folder", {})
    assert as_ingested(a, [row([a], ["a reader no longer installed"], [{"x": 1}])]) == (None, {"x": 1})

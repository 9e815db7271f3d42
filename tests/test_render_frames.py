"""ltc render --recording: a map's boxes drawn into frames of a recording, where that camera saw
them. Edges clipped at the near plane by hand, boxes projected to pixels worked out by hand, the
map frame taken from the session that ingested the recording, the real tum-fr1-rpy frames (when
../shared is there), and the command line's picture, summary and errors."""

import json

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from ltc_cli.cli import cli
from ltc_cli.geometry.boxes import box_corners
from ltc_cli.geometry.camera import invert_pose, transform
from ltc_cli.map.model import SemanticMap
from ltc_cli.map.render_frames import (FRAME_PALETTE, NEAR, clipped_edges, default_frames, draw_boxes, frame_sheet,
                                       in_frustum, map_boxes, project_points, recording_to_map)
from ltc_cli.map.store import save_map
from ltc_cli.recordings.open import open_recording
from ltc_cli.recordings.writer import RecordingWriter
from ltc_cli.types import Intrinsics
from tests.real_truth import TUM_FR1_RPY
from tests.sample_maps import SESSION, add
from tests.shared_data import SHARED

INTR = Intrinsics(640, 480, 500.0, 500.0, 320.0, 240.0)
# The camera at the map's origin looking along +x (OpenCV axes: x right = -y of the map, y down =
# -z, z forward = +x), 1 m above the floor.
T_MAP_CAMERA = np.array([[0, 0, 1, 0], [-1, 0, 0, 0], [0, -1, 0, 1.0], [0, 0, 0, 1.0]])


def test_edges_behind_the_near_plane_are_cut_there():
    # A 2 m cube around the camera's centre plane: its ring at z = -1 lies behind the camera, the
    # ring at z = +1 in front, and the four edges between them cross the plane z = NEAR.
    corners = np.array([[x, y, z] for z in (-1.0, 1.0) for x, y in ((-1, -1), (1, -1), (1, 1), (-1, 1))], float)
    segments = clipped_edges(corners)
    assert segments.shape == (8, 2, 3)  # the 4 edges of the ring behind are gone
    assert (segments[..., 2] >= NEAR - 1e-12).all()
    front_ring = segments[:4]
    assert np.allclose(front_ring[:, :, 2], 1.0)
    crossing = segments[4:]
    # Cut where z = NEAR, straight above its corner (the edge runs along z only).
    assert np.allclose(crossing[:, 0, 2], NEAR) and np.allclose(crossing[:, 1, 2], 1.0)
    assert np.allclose(crossing[:, 0, :2], corners[:4, :2])
    # An oblique edge from (0, 0, -1) to (2, 0, 1) meets z = 0.05 at x = 1.05.
    tilted = corners.copy()
    tilted[0], tilted[4] = [0, 0, -1], [2, 0, 1]
    assert np.allclose(clipped_edges(tilted)[4, 0], [1.05, 0, NEAR])
    assert len(clipped_edges(corners - [0, 0, 5])) == 0  # wholly behind


def test_a_box_is_drawn_where_the_camera_sees_it():
    # A 0.4 m cube 2 m ahead (its centre at the camera's height): its near face (1.8 m) spans
    # 320 +- 500 * 0.2 / 1.8 = 264.4 .. 375.6 px in u and 184.4 .. 295.6 in v; the far face (2.2 m)
    # 274.5 .. 365.5. A second box 2 m behind the camera is not drawn.
    image = np.zeros((480, 640, 3), np.uint8)
    red = (1.0, 0.0, 0.0)
    boxes = [(1, "cup", red, np.array([2.0, 0.0, 1.0]), 0.0, np.array([0.4, 0.4, 0.4])),
             (2, "tv", (0.0, 1.0, 0.0), np.array([-2.0, 0.0, 1.0]), 0.0, np.array([0.4, 0.4, 0.4]))]
    img, seen = draw_boxes(image, boxes, invert_pose(T_MAP_CAMERA), INTR)
    assert seen == {1}
    assert (image == 0).all()  # drawn on a copy
    for u, v in ((320, 184), (320, 296), (264, 240), (376, 240),  # the near face's four sides
                 (320, 195), (275, 240)):  # the far face's top and left sides (195.5, 274.5)
        assert img[v - 1:v + 2, u, 0].max() > 200 and img[v - 1:v + 2, u, 1].max() < 100, (u, v)
    assert not img[230:251, 300:341].any()  # nothing inside the faces
    assert not img[:, :200].any() and not img[:, 440:].any()  # nothing beside the box, nothing green


def test_the_frustum_keeps_every_box_with_an_edge_in_view():
    """2,000 boxes at random around the camera: each one whose clipped edges reach into the image
    (cv2.clipLine, as drawn) passes in_frustum; most of the others do not; beyond max_depth none."""
    import cv2

    rng = np.random.default_rng(3)
    n = 2000
    centers = np.c_[rng.uniform(-6, 6, (n, 2)), rng.uniform(-1, 3, n)]
    sizes = rng.uniform(0.05, 2.0, (n, 3))
    yaws = rng.uniform(-np.pi / 2, np.pi / 2, n)
    T_camera_map = invert_pose(T_MAP_CAMERA)
    keep = in_frustum(centers, sizes, T_camera_map, INTR, 640, 480)
    visible = np.zeros(n, bool)
    for k in range(n):
        corners = transform(T_camera_map, box_corners(centers[k], yaws[k], sizes[k]))
        for p, q in project_points(clipped_edges(corners), INTR):
            if cv2.clipLine((0, 0, 640, 480), tuple(int(round(x)) for x in p), tuple(int(round(x)) for x in q))[0]:
                visible[k] = True
                break
    assert visible.sum() > 200 and (keep[visible]).all()
    assert keep[~visible].mean() < 0.5  # a sphere test: boxes beside the view's corners pass
    near = in_frustum(centers, sizes, T_camera_map, INTR, 640, 480, max_depth=3.0)
    depth = transform(T_camera_map, centers)[:, 2]
    assert not near[depth - 0.5 * np.linalg.norm(sizes, axis=1) > 3.0].any()
    assert near[visible & (depth + 0.5 * np.linalg.norm(sizes, axis=1) < 3.0)].all()


def test_the_map_frame_comes_from_the_session_that_ingested_the_recording():
    smap = SemanticMap.new(["cup"])
    R = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])  # y up -> z up
    smap.sessions = [dict(SESSION, recordings=json.dumps(["other", "rec-A"]),
                          up_rotation=json.dumps([np.eye(3).tolist(), R.tolist()]))]

    class Rec:
        identity = "rec-A"

    T = recording_to_map(smap, Rec())
    assert np.allclose(T[:3, :3], R) and np.allclose(T[:3, 3], 0) and np.allclose(T[3], [0, 0, 0, 1])


def test_default_frames_spread_from_first_to_last():
    """232 frames: 0, 231/3 = 77, 154, 231; five: 0, 4/3, 8/3, 4 rounded; fewer than four: each once."""
    assert default_frames(232) == [0, 77, 154, 231]
    assert default_frames(5) == [0, 1, 3, 4]
    assert default_frames(3) == [0, 1, 2]
    assert default_frames(0) == []


@pytest.fixture()
def scene(tmp_path):
    """A two-frame z-up recording (the camera above, 0.5 m apart) and a map of a cup and a tv in
    front of it, ingested from that recording (its session row names it)."""
    rec = tmp_path / "rec"
    meta = {"format": "ltc-recording/1",
            "camera": {"width": 640, "height": 480, "fx": 500.0, "fy": 500.0, "cx": 320.0, "cy": 240.0},
            "depth": {"scale": 1000.0, "min": 0.3, "max": 6.0}, "up": "z"}
    writer = RecordingWriter(rec, meta)
    for i, dy in enumerate((0.0, 0.5)):
        T = T_MAP_CAMERA.copy()
        T[1, 3] = dy
        writer.write_frame(f"{i:06d}", T, np.full((480, 640, 3), 90, np.uint8), np.full((480, 640), 3000, np.uint16))
    writer.close()
    smap = SemanticMap.new(["cup", "tv"])
    smap.created = "2026-01-01T10:00:00+00:00"
    identity = open_recording(rec).identity
    smap.sessions = [dict(SESSION, recordings=json.dumps([identity]), up_rotation=json.dumps([np.eye(3).tolist()]))]
    add(smap, [2.0, 0.0, 1.0], 0.0, [0.4, 0.4, 0.4], "cup", 0.9)
    add(smap, [2.5, 0.3, 1.2], 0.3, [0.6, 0.1, 0.4], "tv", 0.8)
    m = tmp_path / "m.h5"
    save_map(smap, m)
    return m, rec, smap


def test_frame_sheet_lays_out_the_frames(scene, tmp_path):
    m, rec, smap = scene
    out = tmp_path / "s.png"
    res = frame_sheet(smap, open_recording(rec), [1, 0], out, columns=1, scale=0.5)
    assert res.frames == ["000001", "000000"] and res.in_view == 2
    with Image.open(out) as im:
        assert im.size == (320, 480) == (res.width, res.height)
        sheet = np.asarray(im.convert("RGB"))
    # The cup's near face in frame 0 (second tile): its top side at v 184.4 -> 92 + 240, u 160 at
    # scale 0.5, in the cup's colour (the first class by name).
    cup = np.array(FRAME_PALETTE[0]) * 255
    patch = sheet[240 + 90:240 + 95, 158:163].reshape(-1, 3).astype(float)
    assert np.abs(patch - cup).sum(axis=1).min() < 120
    assert [b[0] for b in map_boxes(smap, {2})] == [2]


def test_ground_truth_is_drawn_beneath_thin_and_grey(scene, tmp_path):
    """A true cup 0.5 m left of the mapped one: its near face's top side runs at v = 240 - 500 *
    0.2 / 1.8 = 184.4 from u = 320 + 500 * 0.3 / 1.8 = 403.3 to 320 + 500 * 0.7 / 1.8 = 514.4."""
    m, rec, smap = scene
    truth = [{"id": 1, "class": "cup", "center": [2.0, -0.5, 1.0], "yaw": 0.0, "size": [0.4, 0.4, 0.4]}]
    out = tmp_path / "gt.png"
    frame_sheet(smap, open_recording(rec), [0], out, columns=1, truth=truth)
    img = np.asarray(Image.open(out).convert("RGB")).astype(int)
    edge = img[183:187, 458]
    assert edge.max() > 150 and np.ptp(edge[edge[:, 0].argmax()]) < 10  # light grey
    assert np.abs(img[240, 458] - 90).max() < 5  # inside the face: the frame as it was
    (rec / "ground_truth.json").write_text(json.dumps({"format": "ltc-ground-truth/1", "lap": 1,
                                                        "objects": truth, "changes": {}}))
    r = CliRunner().invoke(cli, ["render", str(m), "-o", str(out), "--recording", str(rec), "--ground-truth",
                                 str(rec), "--frames", "0"])
    assert r.exit_code == 0 and r.stdout.strip().endswith(", 1 ground-truth box beneath"), r.output


def test_cli_render_into_frames(scene, tmp_path):
    m, rec, _ = scene
    out = tmp_path / "s.png"
    r = CliRunner().invoke(cli, ["render", str(m), "-o", str(out), "--recording", str(rec), "--scale", "0.5"])
    assert r.exit_code == 0, r.output
    assert r.stdout.strip() == f"{out}: 640x240 px, 2 frames of {rec}, 2 objects (2 in view within 6 m)"
    with Image.open(out) as im:
        assert im.size == (640, 240)
    r = CliRunner().invoke(cli, ["render", str(m), "-o", str(out), "--recording", str(rec), "--frames", "1",
                                 "--id", "2"])
    assert r.exit_code == 0 and "1 frame of" in r.stdout and "1 object (1 in view within 6 m)" in r.stdout, r.output
    # A frame named twice is drawn once.
    r = CliRunner().invoke(cli, ["render", str(m), "-o", str(out), "--recording", str(rec), "--frames", "1,0,1"])
    assert r.exit_code == 0 and "2 frames of" in r.stdout, r.output
    with Image.open(out) as im:
        assert im.size == (1280, 480)


@pytest.mark.parametrize("args, words", [
    (["--recording", "REC", "--frames", "0,2"], "frame 2 is not in the recording (frames 0..1)"),
    (["--recording", "REC", "--frames", "a,b"], "is not a list of frame indices"),
    (["--recording", "REC", "--id", "9"], "object 9 is not in the map"),
    (["--recording", "REC", "--width", "300"], "--width draws the top-down picture"),
    (["--recording", "REC", "--changes"], "--changes draws the top-down picture"),
    (["--frames", "0"], "--frames goes with --recording"),
    (["--columns", "3"], "--columns goes with --recording"),
])
def test_cli_usage_errors(scene, tmp_path, args, words):
    m, rec, _ = scene
    out = tmp_path / "s.png"
    r = CliRunner().invoke(cli, ["render", str(m), "-o", str(out)] + [str(rec) if a == "REC" else a for a in args])
    assert r.exit_code == 2 and words in r.output, r.output
    assert not out.exists()


def test_cli_errors_are_one_line(scene, tmp_path):
    m, rec, _ = scene
    for args, words in ((["-o", str(tmp_path / "s.xyz"), "--recording", str(rec)], "cannot write .xyz pictures"),
                        (["-o", str(tmp_path / "s.png"), "--recording", str(tmp_path / "none")], "none")):
        r = CliRunner().invoke(cli, ["render", str(m)] + args)
        lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
        assert r.exit_code == 1 and len(lines) == 1 and words in lines[0], r.output
        assert "Traceback" not in r.output
    assert not list(tmp_path.glob("s.*"))


TUM = SHARED / "data" / "tum-fr1-rpy"


@pytest.mark.skipif(not TUM.is_dir(), reason="../shared/data/tum-fr1-rpy absent")
def test_real_frames_boxes_land_on_the_hand_picked_pixels():
    """On tum-fr1-rpy's own frames (its reader's interpolated poses and camera): a box around each
    hand-measured place (tests/real_truth.py), in a map whose session kept the recording's world
    frame, is drawn around the pixel it was measured at, in that frame. The places were measured
    with the README's camera, the reader takes ROS's default (docs/decisions.md, forty-ninth
    round: cy 16 px apart)."""
    rec = open_recording(TUM)
    smap = SemanticMap.new(["tv", "mouse", "cup", "keyboard", "book", "chair"])
    smap.sessions = [dict(SESSION, recordings=json.dumps([rec.identity]), up_rotation=json.dumps([np.eye(3).tolist()]))]
    places = [lm for lm in TUM_FR1_RPY if lm.cls]
    T_map_world = recording_to_map(smap, rec)
    for lm in places:
        frame = rec.frames[lm.frame].load()
        T_camera_map = invert_pose(T_map_world @ frame.T_world_camera)
        distance = float(np.linalg.norm(T_camera_map[:3, :3] @ lm.world_xyz + T_camera_map[:3, 3]))
        side = 30 * distance / frame.intrinsics.fx  # about 30 px across
        box = (1, lm.cls, (1.0, 0.0, 0.0), np.array(lm.world_xyz), 0.0, np.full(3, side))
        img, seen = draw_boxes(np.zeros_like(frame.rgb), [box], T_camera_map, frame.intrinsics, labels=False)
        assert seen == {1}, lm.name
        # The middle of the drawn outline is the pixel, moved up by the two cameras' cy (255.3 -
        # 239.5 = 15.8 px), give or take the perspective of a box seen at a slant.
        vs, us = np.nonzero(img[..., 0])
        middle = np.array([us.min() + us.max(), vs.min() + vs.max()]) / 2
        assert np.abs(middle - np.add(lm.pixel, [0, -15.8])).max() < 8, (lm.name, middle, lm.pixel)

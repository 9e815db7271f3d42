"""ltc render: a PNG of exactly the requested size, objects where they should be in their class's
colour, ground truth drawn as grey outlines, and clear errors."""

import json

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from ltc_cli.cli import cli
from ltc_cli.errors import LtcError
from ltc_cli.geometry.boxes import box_corners
from ltc_cli.map.render import FILL_ALPHA, PALETTE, class_colour, load_ground_truth, render_map
from ltc_cli.map.store import save_map
from tests.sample_maps import house_map


@pytest.fixture(scope="module")
def house():
    return house_map()


def expected_fill(cls):
    """The footprint fill over the white background, 0-255."""
    return 255 * (FILL_ALPHA * np.array(class_colour(cls)) + (1 - FILL_ALPHA))


def patch(img, col, row, r=2):
    """Median colour of the (2r+1)^2 pixels around (col, row)."""
    c, w = int(col), int(row)
    return np.median(img[w - r: w + r + 1, c - r: c + r + 1].reshape(-1, 3), axis=0)


def test_class_colours_are_fixed_per_name():
    assert class_colour("chair") == class_colour("chair") == class_colour("Chair")
    assert class_colour("chair") != class_colour("table")
    # Unknown names: a palette entry chosen by a CRC of the name (the same in every process).
    palette = {tuple(int(h[i: i + 2], 16) / 255.0 for i in (1, 3, 5)) for h in PALETTE}
    assert class_colour("zebra crossing") in palette and class_colour("class07") in palette
    # The usual furniture never shares a colour.
    usual = ["chair", "table", "sofa", "bed", "tv", "cabinet", "refrigerator", "potted plant", "desk", "sink"]
    assert len({class_colour(c) for c in usual}) == len(usual)


@pytest.mark.parametrize("size", [(1200, 900), (333, 217), (640, 1001)])
def test_png_has_exactly_the_requested_size(house, tmp_path, size):
    out = tmp_path / "m.png"
    res = render_map(house[0], out, width=size[0], height=size[1])
    with Image.open(out) as im:
        assert im.format == "PNG" and im.size == size
    assert (res.width, res.height) == size
    assert not list(tmp_path.glob(".*tmp*"))


def test_objects_are_drawn_where_they_are_in_their_class_colour(house, tmp_path):
    smap, gt = house
    out = tmp_path / "m.png"
    res = render_map(smap, out, width=900, height=700, labels=False)
    img = np.asarray(Image.open(out).convert("RGB")).astype(float)
    t = smap.objects
    checked = 0
    for row in smap.active_rows():
        cls = smap.classes[int(t.scores[row, :-1].argmax())]
        # A point well inside the footprint (a quarter of the way to the first corner), away from
        # the outline; skip footprints that overlap others (the tv lies on the bed).
        corner = box_corners(t.center[row], t.yaw[row], t.size[row])[0, :2]
        p = t.center[row, :2] + 0.25 * (corner - t.center[row, :2])
        if cls in ("bed", "tv") or min(t.size[row, :2]) < 0.3:
            continue
        col, r = res.to_pixel(p)
        np.testing.assert_allclose(patch(img, col, r), expected_fill(cls), atol=6, err_msg=f"{cls} #{row + 1}")
        checked += 1
    assert checked >= 10
    # The empty middle of the flat is background (white, or a light grid line).
    col, r = res.to_pixel([4.6, 2.2])
    assert patch(img, col, r).min() > 220


def test_bounds_and_pixel_transform(tmp_path):
    """With known bounds, a footprint's pixels are where the affine transform says."""
    from ltc_cli.map.model import SemanticMap
    from tests.sample_maps import add

    m = SemanticMap.new(["chair", "table"])
    add(m, [1.0, 1.0, 0.5], 0.0, [1.0, 1.0, 1.0], "table", 0.9)
    add(m, [3.0, 2.0, 0.5], 0.0, [0.6, 0.6, 1.0], "chair", 0.9)
    out = tmp_path / "b.png"
    res = render_map(m, out, width=800, height=800, labels=False, bounds=(0, 4, 0, 3))
    assert res.xlim[0] <= 0 and res.xlim[1] >= 4 and res.ylim[0] <= 0 and res.ylim[1] >= 3
    img = np.asarray(Image.open(out).convert("RGB")).astype(float)
    # y up in the map is up in the picture: the table's top edge has a smaller row than its bottom.
    (c0, r0), (c1, r1) = res.to_pixel([[0.5, 0.5], [1.5, 1.5]])
    assert c1 > c0 and r1 < r0
    # Equal scale on both axes.
    assert abs(c1 - c0) == pytest.approx(abs(r1 - r0), rel=1e-6)
    np.testing.assert_allclose(patch(img, *res.to_pixel([1.2, 0.8])), expected_fill("table"), atol=6)
    np.testing.assert_allclose(patch(img, *res.to_pixel([3.1, 2.1])), expected_fill("chair"), atol=6)
    assert patch(img, *res.to_pixel([2.2, 2.6])).min() > 220  # between them: background


def test_ground_truth_is_drawn_beneath_as_grey_outlines(house, tmp_path):
    smap, gt = house
    a, b = tmp_path / "a.png", tmp_path / "b.png"
    render_map(smap, a, width=900, height=700, labels=False)
    res = render_map(smap, b, width=900, height=700, labels=False, ground_truth=gt)
    img_a = np.asarray(Image.open(a).convert("RGB")).astype(int)
    img_b = np.asarray(Image.open(b).convert("RGB")).astype(int)
    # The chair the robot missed (ground truth id 15) only exists in the ground truth: its outline
    # appears in b, in grey (r = g = b, darker than the background).
    missed = gt[14]
    ring = box_corners(missed["center"], missed["yaw"], missed["size"])[:4, :2]
    cols_rows = res.to_pixel(ring)
    c0, r0 = np.floor(cols_rows.min(axis=0)).astype(int) - 2
    c1, r1 = np.ceil(cols_rows.max(axis=0)).astype(int) + 2
    diff = np.abs(img_b[r0:r1, c0:c1] - img_a[r0:r1, c0:c1]).sum(axis=2) > 30
    assert diff.sum() > 40
    changed = img_b[r0:r1, c0:c1][diff]
    assert np.all(np.ptp(changed, axis=1) < 25)  # grey, anti-aliased at the edges
    assert changed.mean(axis=1).min() < 130
    # Nothing changes far from any ground-truth box (e.g. the empty middle of the flat).
    col, r = res.to_pixel([4.6, 2.2]).astype(int)
    assert np.array_equal(img_a[r - 3: r + 4, col - 3: col + 4], img_b[r - 3: r + 4, col - 3: col + 4])


def test_empty_map_still_renders(tmp_path):
    from ltc_cli.map.model import SemanticMap

    res = render_map(SemanticMap.new(["chair"]), tmp_path / "e.png", width=300, height=200)
    assert Image.open(res.path).size == (300, 200) and res.objects == 0


def test_bad_sizes_and_ground_truth(house, tmp_path):
    with pytest.raises(LtcError, match="width"):
        render_map(house[0], tmp_path / "x.png", width=10, height=300)
    bad = tmp_path / "gt.json"
    bad.write_text(json.dumps({"objects": [{"id": 1, "class": "chair", "center": [0, 0], "yaw": 0, "size": [1, 1, 1]}]}))
    with pytest.raises(LtcError, match=r"gt\.json: at objects\.0\.center"):
        load_ground_truth(bad)
    with pytest.raises(LtcError, match="no ground_truth.json in this recording folder"):
        load_ground_truth(tmp_path)


def test_cli_render(house, tmp_path):
    smap, gt = house
    m = tmp_path / "house.h5"
    save_map(smap, m)
    rec = tmp_path / "lap1"
    rec.mkdir()
    (rec / "ground_truth.json").write_text(json.dumps({"format": "ltc-ground-truth/1", "objects": gt}))
    out = tmp_path / "house.png"
    r = CliRunner().invoke(cli, ["render", str(m), "-o", str(out), "--ground-truth", str(rec),
                                 "--width", "640", "--height", "480", "--no-labels"])
    assert r.exit_code == 0, r.output
    assert r.stdout.strip() == f"{out}: 640x480 px, 15 objects, 15 ground-truth boxes"
    assert Image.open(out).size == (640, 480)
    # Errors: one line naming the file, exit 1; bad sizes are usage errors (exit 2).
    r = CliRunner().invoke(cli, ["render", str(m), "-o", str(out), "--ground-truth", str(tmp_path / "nope.json")])
    assert r.exit_code == 1 and "nope.json" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    r = CliRunner().invoke(cli, ["render", str(m), "-o", str(out), "--width", "5"])
    assert r.exit_code == 2
    r = CliRunner().invoke(cli, ["render", str(m), "-o", str(tmp_path / "no-dir" / "x.png")])
    assert r.exit_code == 1 and "x.png" in r.stderr and len(r.stderr.strip().splitlines()) == 1

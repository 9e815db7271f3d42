"""ltc render's legibility: a distinct colour for every class of a picture, labels that do not
cover each other, and the picture format chosen by the output's suffix."""

from __future__ import annotations

import itertools

import pytest
from click.testing import CliRunner
from PIL import Image

from ltc_cli.cli import cli
from ltc_cli.map.model import SemanticMap
from ltc_cli.map.render import RenderError, class_colour, class_colours, render_map
from ltc_cli.map.store import save_map
from ltc_cli.tools.simulate import CLASSES
from tests.sample_maps import add

COCO = ["person", "bicycle", "car", "motorcycle", "airplane", "bus", "train", "truck", "boat", "traffic light",
        "fire hydrant", "stop sign", "parking meter", "bench", "bird", "cat", "dog", "horse", "sheep", "cow",
        "elephant", "bear", "zebra", "giraffe", "backpack", "umbrella", "handbag", "tie", "suitcase", "frisbee",
        "skis", "snowboard", "sports ball", "kite", "baseball bat", "baseball glove", "skateboard", "surfboard",
        "tennis racket", "bottle", "wine glass", "cup", "fork", "knife", "spoon", "bowl", "banana", "apple",
        "sandwich", "orange", "broccoli", "carrot", "hot dog", "pizza", "donut", "cake", "chair", "couch",
        "potted plant", "bed", "dining table", "toilet", "tv", "laptop", "mouse", "remote", "keyboard",
        "cell phone", "microwave", "oven", "toaster", "sink", "refrigerator", "book", "clock", "vase", "scissors",
        "teddy bear", "hair drier", "toothbrush"]


def test_every_class_of_a_picture_has_its_own_colour():
    # By name alone, oven and cup share a palette entry; in one picture they must not.
    assert class_colour("oven") == class_colour("cup")
    sim = class_colours(CLASSES)
    assert len(set(sim.values())) == len(CLASSES) == 15
    coco = class_colours(COCO)
    assert len(set(coco.values())) == 80
    # Common classes keep their colour of every picture.
    for name in ("chair", "dining table", "couch", "tv", "bed"):
        assert sim[name] == coco[name] == class_colour(name)


def crowded_map() -> SemanticMap:
    """Twelve small objects of twelve classes packed into 0.35 m x 0.1 m: their labels would overlap."""
    names = list(CLASSES[:12])
    m = SemanticMap.new(names)
    for k, name in enumerate(names):
        add(m, [0.06 * (k % 6), 0.04 * (k // 6), 0.4], 0.0, [0.03, 0.03, 0.4], name, 0.8)
    return m


def test_labels_do_not_overlap(tmp_path):
    res = render_map(crowded_map(), tmp_path / "m.png", width=700, height=500, labels=True)
    boxes = res.label_boxes
    assert len(boxes) >= 8  # most find a place; one with none is left out rather than drawn over another
    for a, b in itertools.combinations(boxes, 2):
        assert a[2] <= b[0] or b[2] <= a[0] or a[3] <= b[1] or b[3] <= a[1], (a, b)


@pytest.mark.parametrize("suffix,fmt", [(".jpg", "JPEG"), (".jpeg", "JPEG"), (".png", "PNG"), ("", "PNG"),
                                        (".webp", "WEBP")])
def test_picture_format_follows_the_suffix(tmp_path, suffix, fmt):
    out = tmp_path / f"m{suffix}"
    render_map(crowded_map(), out, width=300, height=200)
    with Image.open(out) as im:
        assert im.format == fmt and im.size == (300, 200)


def test_unknown_picture_suffix_is_one_line(tmp_path):
    with pytest.raises(RenderError, match=r"cannot write \.gif pictures"):
        render_map(crowded_map(), tmp_path / "m.gif")
    save_map(crowded_map(), tmp_path / "m.h5")
    r = CliRunner().invoke(cli, ["render", str(tmp_path / "m.h5"), "-o", str(tmp_path / "m.gif")])
    assert r.exit_code == 1 and len(r.output.strip().splitlines()) == 1 and "m.gif" in r.output
    assert not (tmp_path / "m.gif").exists()
    r = CliRunner().invoke(cli, ["render", str(tmp_path / "m.h5"), "-o", str(tmp_path / "m.jpg")])
    assert r.exit_code == 0 and "px JPEG" in r.output
    assert (tmp_path / "m.jpg").read_bytes()[:2] == b"\xff\xd8"  # JPEG's start-of-image marker

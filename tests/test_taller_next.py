"""modeling.taller_than with ``is: next`` (issue 9, eighth round): a detection whose box is taller
than any object of its top class goes to the detection's own next most likely class. Expected
vectors are worked out by hand."""

import numpy as np
import pytest

from ltc_cli.config import defaults
from ltc_cli.map.model import top_class
from ltc_cli.pipeline.frame_modeling import NEXT, ClassFlags, model_frame, relabel_too_tall
from tests.scene import INTR, T_world_camera, render

CLASSES = ["bottle", "potted plant", "cup", "vase"]  # then other
BOTTLE, PLANT, CUP, VASE, OTHER = 0, 1, 2, 3, 4
LIMIT = np.array([0.5, np.inf, np.inf, np.inf, np.inf])
TO = np.array([NEXT, -1, -1, -1, -1])


def test_the_score_goes_to_the_detections_next_class():
    """bottle 0.6, potted plant 0.25, cup 0.05, vase 0, other 0.1: a 0.77 m box moves the 0.6 to the
    plant (0.85); other (0.1, more than the cup) is never the next class; a 0.3 m box stays."""
    v = np.array([0.6, 0.25, 0.05, 0.0, 0.1])
    out = relabel_too_tall([v, v], np.array([0, 1]), np.array([0.77, 0.30]), LIMIT, TO)
    assert out[0] == pytest.approx([0.0, 0.85, 0.05, 0.0, 0.1])
    assert out[1] == pytest.approx(v)
    # The next class is the detection's, not a fixed one: here the vase (0.3) is second.
    w = np.array([0.6, 0.0, 0.1, 0.3, 0.0])
    assert relabel_too_tall([w], np.array([0]), np.array([0.77]), LIMIT, TO)[0] == pytest.approx(
        [0.0, 0.0, 0.1, 0.9, 0.0])


def test_a_detection_with_no_second_class_keeps_its_label():
    """A one-hot vector (Mask R-CNN gives one score per instance) says nothing about what else the
    box is: it stays a bottle, the only class with a score."""
    v = np.array([0.9, 0.0, 0.0, 0.0, 0.1])
    assert relabel_too_tall([v], np.array([0]), np.array([0.77]), LIMIT, TO)[0] == pytest.approx(v)


def test_flags_from_settings_and_the_default():
    cfg = defaults()
    assert cfg["modeling"]["taller_than"]["bottle"] == {"height": 0.5, "is": "next"}
    flags = ClassFlags.from_settings(CLASSES, cfg)
    assert flags.max_height[BOTTLE] == 0.5 and flags.taller_is[BOTTLE] == NEXT
    assert (flags.taller_is[[PLANT, CUP, VASE, OTHER]] == -1).all()


@pytest.mark.parametrize("z_top, expected", [(1.6, "potted plant"), (1.1, "bottle")])
def test_stage_1_calls_a_bottle_taller_than_any_bottle_its_next_class(z_top, expected):
    """A 0.4 m wide face 2 m ahead from z 0.8 up to z_top, detected as bottle 0.6 with potted plant
    0.25 second: 0.8 m tall it comes out a plant; 0.3 m tall it stays a bottle."""
    cfg = defaults()
    depth, masks = render([(2.0, 2.05, -0.2, 0.2, 0.8, z_top)], wall_x=4.0)
    flags = ClassFlags.from_settings(CLASSES, cfg)
    v = np.array([0.6, 0.25, 0.05, 0.0, 0.1])
    out = model_frame(masks, [v], depth, T_world_camera(), INTR, (0.3, 6.0), cfg, flags)
    assert len(out.modeled.source) == 1
    assert CLASSES[int(top_class(out.scores[0]))] == expected

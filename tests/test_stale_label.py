"""integration.stale_label_weight (issue 9, twenty-second round): the class vector of an object last
detected in an earlier session weighs at most this much against the first detection of a new
session whose top class differs. Expected vectors are eq. 3 worked out by hand."""

import numpy as np
import pytest
import yaml
from pathlib import Path

from ltc_cli import plugins
from ltc_cli.config import defaults
from ltc_cli.geometry.boxes import Box
from ltc_cli.map.model import ACTIVE, SemanticMap
from ltc_cli.pipeline.mapper import Mapper

CLASSES = ["oven", "refrigerator"]  # then other


def oven_box():
    return Box(np.array([2.0, 0.0, 0.45]), 0.0, np.array([0.6, 0.6, 0.9]), np.ones(8, bool), True)


def mapper_with(scores, session, cap):
    """A map holding one object of 30 detections (session 0) with class vector ``scores``, and a
    mapper of ``session``; max_weight 20 and relabel_weight all as the defaults."""
    cfg = defaults()
    cfg["integration"]["stale_label_weight"] = cap
    assert cfg["integration"]["max_weight"] == 20 and cfg["integration"]["relabel_weight"] == "all"
    smap = SemanticMap.new(CLASSES)
    b = oven_box()
    row = smap.objects.append(center=b.center, yaw=b.yaw, size=b.size, visible=b.visible, defined=True,
                              scores=np.array(scores, dtype=float), n_det=30, status=ACTIVE, first_session=0,
                              last_session=0)
    mapper = Mapper(smap, cfg, plugins.get("metrics", "vertex").factory(cfg["association"]),
                    plugins.get("policies", "non-detection").factory(cfg["maintenance"]), session=session)
    return mapper, row


@pytest.mark.parametrize("session, cap, expected", [
    # Stale, capped at 3: (0.85, 0.10, 0.05) + 3 (0.40, 0.55, 0.05) = (2.05, 1.75, 0.20) / 4.
    (1, 3, [0.5125, 0.4375, 0.05]),
    # No cap: relabel_weight all weighs all 30 observations: (12.85, 16.60, 1.55) / 31.
    (1, None, [12.85 / 31, 16.6 / 31, 1.55 / 31]),
    # Detected in this session already (session 0): not stale, 30 as well.
    (0, 3, [12.85 / 31, 16.6 / 31, 1.55 / 31]),
])
def test_a_weak_label_reopens_at_a_new_sessions_first_detection(session, cap, expected):
    mapper, row = mapper_with([0.40, 0.55, 0.05], session, cap)
    mapper._integrate(row, oven_box(), np.array([0.85, 0.10, 0.05]), 0, "0")
    assert mapper.map.objects.scores[row] == pytest.approx(expected)


def test_a_clear_label_stays_and_later_detections_weigh_as_before():
    # A clear oven (0.8 / 0.1) against a first "refrigerator" detection of a new session:
    # (0.05, 0.90, 0.05) + 3 (0.80, 0.10, 0.10) = (2.45, 1.20, 0.35) / 4: still an oven.
    mapper, row = mapper_with([0.80, 0.10, 0.10], 1, 3)
    mapper._integrate(row, oven_box(), np.array([0.05, 0.90, 0.05]), 0, "0")
    assert mapper.map.objects.scores[row] == pytest.approx([0.6125, 0.3, 0.0875])


def test_only_the_first_detection_of_a_session_is_capped():
    # After the weak label re-opened to oven (0.5125, 0.4375, 0.05; 31 detections), the next
    # "refrigerator" detection of the same session weighs all 31 observations:
    # (0.05 + 31 x 0.5125, 0.90 + 31 x 0.4375, 0.05 + 31 x 0.05) / 32.
    mapper, row = mapper_with([0.40, 0.55, 0.05], 1, 3)
    mapper._integrate(row, oven_box(), np.array([0.85, 0.10, 0.05]), 0, "0")
    mapper._integrate(row, oven_box(), np.array([0.05, 0.90, 0.05]), 1, "1")
    expected = np.array([0.05 + 31 * 0.5125, 0.90 + 31 * 0.4375, 0.05 + 31 * 0.05]) / 32
    assert mapper.map.objects.scores[row] == pytest.approx(expected)
    assert int(np.argmax(mapper.map.objects.scores[row])) == 0  # still an oven


def test_default_and_paper():
    assert defaults()["integration"]["stale_label_weight"] is None  # measured, not adopted (decisions.md)
    paper = yaml.safe_load((Path(__file__).resolve().parent.parent / "docs" / "paper.yaml").read_text())
    assert paper["integration"]["stale_label_weight"] is None

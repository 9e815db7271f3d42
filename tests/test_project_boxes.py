"""benchmarks/project_boxes.py's choice of frames, against indices worked out by hand."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
from project_boxes import frame_indices  # noqa: E402


def test_four_frames_spread_evenly_by_default():
    """232 frames: 0, 231/3 = 77, 2 x 77 = 154, 231. Five frames: 0, 4/3, 8/3, 4 rounded to 0, 1, 3,
    4. Two frames: both, once each."""
    assert frame_indices(None, 232) == [0, 77, 154, 231]
    assert frame_indices(None, 5) == [0, 1, 3, 4]
    assert frame_indices(None, 2) == [0, 1]


def test_indices_past_the_end_mean_the_last_frame_drawn_once():
    """The old default 0,60,120,180 on the five-frame dining room drew its last frame three times."""
    assert frame_indices("0,60,120,180", 5) == [0, 4]
    assert frame_indices("3,1,3", 10) == [3, 1]

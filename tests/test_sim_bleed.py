"""The simulator's mask bleed is for a 640 x 480 image and grows with a larger image (issue 9,
fiftieth round), as a CNN's does: YOLOv8-seg's masks come from an 80 x 80 grid over its input."""

import yaml

from ltc_cli.tools.simulate import simulate
from ltc_cli.tools.simulate.laps import bleed_at


def test_bleed_at_by_hand():
    assert bleed_at(3, 640, 480) == 3
    assert bleed_at(3, 1280, 960) == 6      # 3 * 2
    assert bleed_at(3, 960, 720) == 5       # 3 * 1.5 = 4.5, rounded half up
    assert bleed_at(3, 1280, 720) == 6      # by the longer side
    assert bleed_at(3, 320, 240) == 3       # smaller images keep the pixels
    assert bleed_at(0, 1280, 960) == 0      # no bleed stays none


def test_the_recording_states_the_option_as_given(tmp_path):
    simulate(tmp_path / "sim", scene="tiny", laps=1, seed=3, width=1280, height=960,
             frames_per_room=2)
    meta = yaml.safe_load((tmp_path / "sim" / "lap1" / "recording.yaml").read_text())
    assert meta["simulator"]["options"]["bleed_px"] == 3

"""tum-fr1-rpy (../shared) mapped with the int8 copy of the shared YOLOv8n-seg, the model as it
was shared (the fp32 copy, which tests/test_real_revisits.py uses, runs 3-4 times faster and names
things a little differently). One session forward and one read backwards: as the README counts,
and every place measured by hand held right (tests/real_truth.py).

Two rules of the thirty-second round (docs/decisions.md), each needed:
- ``modeling.taller_than`` holds "mouse" to 0.12 m. Before, the second monitor's foot stayed a
  "mouse" in session 1: its screen's box, 0.36 m long, put the foot 0.31 of its length from its
  middle, past ``stand_centred``, and the foot's box, 0.13 m tall, was over ``stand_low``. Its
  views 0.12-0.13 m tall now count for the monitor.
- ``stand_centred`` takes a foot whose bottom lies up to ``stand_gap`` above its screen box's.
  Read backwards, the front foot's tall views, now "tv", take the screen's box down to the desk
  (z 0.725), and the plate's "mouse" box (z 0.73-0.79) stood inside it.
Skipped when ../shared is absent.
"""

from pathlib import Path

import pytest

from ltc_cli import hookimpl, plugins
from ltc_cli.config import load_config
from ltc_cli.ingest.session import ingest
from ltc_cli.map.store import load_map
from tests.real_truth import COUNTS, check
from tests.replay import Reordered, Replay
from tests.test_real_revisits import census

SHARED = Path(__file__).resolve().parents[2] / "shared"
DATA = SHARED / "data" / "tum-fr1-rpy"
MODEL = SHARED / "models" / "yolov8n-seg_int8.onnx"

pytestmark = pytest.mark.skipif(not (DATA.is_dir() and MODEL.is_file()), reason="../shared data or model absent")


class Int8Plugin:
    @hookimpl
    def register_detectors(self, register):
        register("cached-yolo-int8", Replay)

    @hookimpl
    def register_readers(self, register):
        register("backwards-int8", Reordered(reverse=True))


@pytest.fixture(scope="module")
def mapped(tmp_path_factory):
    plugins.register_plugin(Int8Plugin(), name="test-real-int8")
    cfg = load_config(None, ["detector.name=cached-yolo-int8", f"detector.options.model={MODEL}"])
    out = {}
    for name, reader in (("forward", None), ("backwards", "backwards-int8")):
        out[name] = tmp_path_factory.mktemp("int8") / f"{name}.h5"
        ingest([DATA], out[name], cfg, reader=reader)
    yield out
    plugins.unregister_plugin("test-real-int8")


@pytest.mark.parametrize("name", ["forward", "backwards"])
def test_one_session_with_the_int8_model_is_as_counted_and_holds_every_place(mapped, name):
    counts, _ = census(mapped[name])
    truth = COUNTS["tum-fr1-rpy"]
    off = [f"{c} {n}" for c, n in counts.items() if not truth.get(c, (0, 0))[0] <= n <= truth.get(c, (0, 0))[1]]
    assert off == [] and all(counts.get(c, 0) >= lo for c, (lo, _) in truth.items())
    wrong = [f"{lm.name}: {where}" for lm, ok, where in check(load_map(mapped[name])) if not ok]
    assert wrong == []

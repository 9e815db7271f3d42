"""tum-fr1-rpy (../shared) mapped with the int8 copy of the shared YOLOv8n-seg, the model as it
was shared (the fp32 copy, which tests/test_real_revisits.py uses, runs 3-4 times faster and names
things a little differently). One session forward and one read backwards, each as the README
counts. Forward, every place measured by hand is held right (tests/real_truth.py); backwards,
every thing's place (the front monitor's foot stays a "mouse" there, see below).

Before ``modeling.taller_than`` held "mouse" to 0.12 m (docs/decisions.md, thirty-second round),
the second monitor's foot stayed a "mouse" in session 1: its screen's box, 0.36 m long, put the
foot 0.31 of its length from its middle, past ``stand_centred``, and the foot's box, 0.13 m tall,
was over ``stand_low``. Its views 0.12-0.13 m tall now count for the monitor. Read backwards, the
front foot's tall views, now "tv", take the screen's box down to the desk (z 0.725), and the
plate's "mouse" box (z 0.73-0.79) stands inside it, its bottom 5 mm above the box's, which the
stand rules do not take (letting them took a keyboard into a phantom "suitcase" over the desk).
Skipped when ../shared is absent.
"""


import pytest

from ltc_cli import hookimpl, plugins
from ltc_cli.config import load_config
from ltc_cli.ingest.session import ingest
from ltc_cli.map.store import load_map
from tests.real_truth import APART, COUNTS, check, merged_pairs
from tests.replay import Reordered, Replay
from tests.test_real_revisits import census
from tests.shared_data import SHARED

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
def test_one_session_with_the_int8_model_is_as_counted_and_holds_the_places(mapped, name):
    """Forward, no box holds two things of one class (``APART``; the trackball and the game
    controller were one "mouse" box before ``association.seen_apart_gap``, thirty-third round).
    Read backwards with int8 they are still one box (docs/decisions.md, thirty-third round)."""
    counts, _ = census(mapped[name])
    truth = COUNTS["tum-fr1-rpy"]
    off = [f"{c} {n}" for c, n in counts.items() if not truth.get(c, (0, 0))[0] <= n <= truth.get(c, (0, 0))[1]]
    assert off == [] and all(counts.get(c, 0) >= lo for c, (lo, _) in truth.items())
    wrong = [f"{lm.name}: {where}" for lm, ok, where in check(load_map(mapped[name]))
             if not ok and (name == "forward" or lm.cls is not None)]
    assert wrong == []
    if name == "forward":
        assert merged_pairs(load_map(mapped[name]), APART["tum-fr1-rpy"]) == []

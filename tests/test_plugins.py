"""Every hook of ltc_cli/hookspecs.py, exercised by a third-party plugin registered at run time."""

import numpy as np
import pluggy
import pytest
from click.testing import CliRunner

from ltc_cli import hookimpl, plugins
from ltc_cli.cli import cli
from ltc_cli.config import defaults
from ltc_cli.errors import PluginError
from ltc_cli.ingest.session import ingest
from ltc_cli.recordings.open import open_recording
from ltc_cli.map.model import ACTIVE
from ltc_cli.map.store import load_map
from ltc_plugins.readers.ltc_recording import LtcRecordingReader
from tests.recording import write_recording

CALLS = {"metric": 0, "policy": 0, "detect": 0, "sniff": 0}


class FarMetric:
    """Every candidate is 'far': no detection ever matches, so each makes a new object."""

    def __init__(self, options):
        pass

    def distance(self, det, cands):
        CALLS["metric"] += 1
        return np.full(len(cands), 99.0)


class RemoveAllPolicy:
    """Every unmatched object in view gets a non-detection, however little of it is visible."""

    def __init__(self, options):
        pass

    def non_detections(self, matched, visible_px, required_px):
        CALLS["policy"] += 1
        return ~np.asarray(matched, bool) & (np.asarray(visible_px) > 0)


class OnlyTables:
    """A detector that replays the recorded detections and keeps the tables only."""

    def __init__(self, recording, options):
        from ltc_plugins.recorded import RecordedDetector

        self.inner = RecordedDetector.from_options(recording, {})
        self.classes = ["table"]

    def detect(self, frame):
        CALLS["detect"] += 1
        i = self.inner.classes.index("table")
        return [type(d)(d.mask, d.scores[[i]]) for d in self.inner.detect(frame) if d.scores.argmax() == i]


class MarkedReader(LtcRecordingReader):
    """ltc-recording/1 folders that carry a MARK file."""

    @staticmethod
    def sniff(path):
        CALLS["sniff"] += 1
        return (path / "MARK").is_file()


class ThirdParty:
    @hookimpl
    def register_metrics(self, register):
        register("far", FarMetric)

    @hookimpl
    def register_policies(self, register):
        register("remove-all", RemoveAllPolicy)

    @hookimpl
    def register_detectors(self, register):
        register("only-tables", OnlyTables)

    @hookimpl
    def register_readers(self, register):
        register("marked", MarkedReader)


@pytest.fixture
def third_party():
    plugins.register_plugin(ThirdParty(), name="third-party")
    yield
    plugins.unregister_plugin("third-party")


@pytest.fixture(scope="module")
def rec(tmp_path_factory):
    return write_recording(tmp_path_factory.mktemp("rec") / "rec")


def test_builtins_are_registered_through_entry_points():
    pm = plugins.get_plugin_manager()
    dists = {p: d.project_name for p, d in pm.list_plugin_distinfo()}
    for module in ("recorded", "metrics", "policies", "ltc_recording", "readers", "onnx_yolo_seg", "onnx_maskrcnn"):
        plugin = pm.get_plugin(module)
        assert plugin is not None and dists[plugin] == "ltc", module
    assert {"recorded", "onnx-yolo-seg", "onnx-maskrcnn"} <= set(plugins.registry("detectors"))
    assert {"vertex", "centroid"} <= set(plugins.registry("metrics"))
    assert {"non-detection", "static"} <= set(plugins.registry("policies"))
    assert {"ltc-recording", "tum", "7scenes", "scannet"} <= set(plugins.registry("readers"))


def test_metric_hook(third_party, rec, tmp_path):
    cfg = defaults()
    cfg["association"]["metric"] = "far"
    cfg["association"]["containment"] = None
    cfg["association"]["containment_other_class"] = None
    cfg["maintenance"]["min_detections"] = 1
    before = CALLS["metric"]
    ingest([rec], tmp_path / "m.h5", cfg)
    assert CALLS["metric"] > before
    kinds = {e.kind for e in load_map(tmp_path / "m.h5").events}
    assert "created" in kinds and not kinds & {"updated", "merged"}  # nothing ever matched


def test_policy_hook(third_party, rec, tmp_path):
    cfg = defaults()
    cfg["maintenance"]["policy"] = "remove-all"
    before = CALLS["policy"]
    ingest([rec], tmp_path / "m.h5", cfg)
    assert CALLS["policy"] > before
    assert load_map(tmp_path / "m.h5").sessions[0]["policy"] == "remove-all"


def test_detector_hook(third_party, rec, tmp_path):
    cfg = defaults()
    cfg["detector"]["name"] = "only-tables"
    before = CALLS["detect"]
    s = ingest([rec], tmp_path / "m.h5", cfg)
    assert s.frames_done == 5 and CALLS["detect"] == before + 5
    smap = load_map(tmp_path / "m.h5")
    t = smap.objects
    top = {smap.classes[int(t.scores[r, :-1].argmax())] for r in np.flatnonzero(t.status == ACTIVE)}
    assert top == {"table"}


def test_reader_hook(third_party, tmp_path):
    r = write_recording(tmp_path / "marked")
    (r / "MARK").write_text("")
    # Both it and ltc-recording recognise this folder: choose it by name.
    got = open_recording(r, reader="marked")
    assert got.format == "ltc-recording/1" and len(got) == 5
    r2 = CliRunner().invoke(cli, ["ingest", str(r), "--map", str(tmp_path / "m.h5"), "--format", "marked"])
    assert r2.exit_code == 0, r2.output
    # Automatic choice: a folder only the third-party reader claims goes to it.
    other = tmp_path / "other"
    other.mkdir()
    (other / "MARK").write_text("")
    before = CALLS["sniff"]
    from ltc_cli.errors import RecordingError

    with pytest.raises(RecordingError, match="recording.yaml is missing"):
        open_recording(other)
    assert CALLS["sniff"] > before


def test_plugins_command_lists_hooks_and_names(third_party):
    r = CliRunner().invoke(cli, ["plugins"])
    assert r.exit_code == 0
    out = r.output
    assert "third-party" in out and "register_metrics" in out and "far" in out and "remove-all" in out
    assert "onnx-yolo-seg" in out and "register_readers" in out
    assert out.strip().splitlines()[-1].endswith("readers")


def test_a_name_registered_twice_is_an_error():
    class Clash:
        @hookimpl
        def register_metrics(self, register):
            register("vertex", FarMetric)

    plugins.register_plugin(Clash(), name="clash")
    try:
        with pytest.raises(PluginError, match="registered twice"):
            plugins.registry("metrics")
    finally:
        plugins.unregister_plugin("clash")


def test_unknown_hook_is_refused_when_loading(monkeypatch):
    class Typo:
        @hookimpl
        def register_metric(self, register):  # not a hook: a typo of register_metrics
            pass

    pm = pluggy.PluginManager("ltc")
    from ltc_cli import hookspecs

    pm.add_hookspecs(hookspecs)
    pm.register(Typo())
    with pytest.raises(pluggy.PluginValidationError):
        pm.check_pending()


def test_ltc_plugins_env_names_a_missing_module(monkeypatch):
    monkeypatch.setenv("LTC_PLUGINS", "no_such_module_xyz")
    plugins.reset()
    try:
        with pytest.raises(PluginError, match="no_such_module_xyz"):
            plugins.get_plugin_manager()
    finally:
        monkeypatch.delenv("LTC_PLUGINS")
        plugins.reset()


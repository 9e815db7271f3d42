"""The ONNX detectors' execution provider option (issue 11): cpu, openvino, auto."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from ltc_cli.cli import cli
from ltc_cli.errors import PluginError
from ltc_plugins.onnx.common import OPENVINO, execution_providers

CPU = "CPUExecutionProvider"


def test_cpu_is_cpu_even_with_openvino_installed():
    assert execution_providers("cpu", [OPENVINO, CPU], 2, "x") == [CPU]


def test_auto_takes_openvino_when_installed_with_the_threads_and_cpu_behind():
    assert execution_providers("auto", [OPENVINO, CPU], 2, "x") == [
        (OPENVINO, {"device_type": "CPU", "num_of_threads": "2"}), CPU]
    assert execution_providers("auto", [CPU], 2, "x") == [CPU]


def test_openvino_missing_says_what_to_install():
    with pytest.raises(PluginError, match=r"^x: provider openvino needs onnxruntime-openvino .*ltc\[openvino\].*"
                                          r"this onnxruntime has AzureExecutionProvider, CPUExecutionProvider$"):
        execution_providers("openvino", ["AzureExecutionProvider", CPU], 1, "x")


def test_cli_asked_for_missing_openvino_fails_in_one_line(tmp_path):
    pytest.importorskip("onnx")
    ort = pytest.importorskip("onnxruntime")
    if OPENVINO in ort.get_available_providers():
        pytest.skip("onnxruntime-openvino is installed here")
    from tests.test_onnx_detectors import YOLO_META, const_model, yolo_outputs

    model = const_model(tmp_path / "tiny-seg.onnx", ("images", [1, 3, 32, 32]), yolo_outputs(), YOLO_META)
    lap1 = Path(__file__).resolve().parent.parent / "sample_data" / "lap1"
    m = tmp_path / "m.h5"
    r = CliRunner().invoke(cli, ["ingest", str(lap1), "--map", str(m), "--detector", "onnx-yolo-seg",
                                 "--set", f"detector.options.model={model}", "--set", "detector.options.provider=openvino"])
    assert r.exit_code == 1
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and "provider openvino needs onnxruntime-openvino" in lines[0], r.output
    assert "Traceback" not in r.output and not m.exists()


def test_bad_provider_is_refused():
    with pytest.raises(PluginError, match="provider"):
        from ltc_plugins.onnx.yolo_seg import YoloSegDetector

        YoloSegDetector.from_options(None, {"model": __file__, "provider": "cuda"})


def test_precision_becomes_openvinos_hint():
    assert execution_providers("openvino", [OPENVINO, CPU], 1, "x", "bf16") == [
        (OPENVINO, {"device_type": "CPU", "num_of_threads": "1",
                    "load_config": '{"CPU": {"INFERENCE_PRECISION_HINT": "bf16"}}'}), CPU]
    assert execution_providers("openvino", [OPENVINO, CPU], 1, "x", "f32") == [
        (OPENVINO, {"device_type": "CPU", "num_of_threads": "1"}), CPU]
    assert execution_providers("auto", [CPU], 1, "x", "bf16") == [CPU]  # auto without OpenVINO: f32 on cpu
    with pytest.raises(PluginError, match=r"^x: precision bf16 needs provider openvino"):
        execution_providers("cpu", [OPENVINO, CPU], 1, "x", "bf16")


@pytest.mark.filterwarnings("ignore:Specified provider")
def test_openvino_that_does_not_start_is_an_error_not_a_silent_cpu_run(tmp_path, monkeypatch):
    # onnxruntime only warns and runs on its CPU provider when a provider it is given cannot start.
    pytest.importorskip("onnx")
    ort = pytest.importorskip("onnxruntime")
    if OPENVINO in ort.get_available_providers():
        pytest.skip("onnxruntime-openvino is installed here")
    from ltc_plugins.onnx import common
    from ltc_plugins.onnx.yolo_seg import YoloSegDetector
    from tests.test_onnx_detectors import YOLO_META, const_model, yolo_outputs

    model = const_model(tmp_path / "tiny-seg.onnx", ("images", [1, 3, 32, 32]), yolo_outputs(), YOLO_META)
    monkeypatch.setattr(common, "execution_providers", lambda *a: [(OPENVINO, {"device_type": "CPU"}), CPU])
    with pytest.raises(PluginError, match="could not start its OpenVINO provider") as err:
        YoloSegDetector.from_options(None, {"model": str(model), "provider": "openvino"})
    assert err.value.path == str(model)

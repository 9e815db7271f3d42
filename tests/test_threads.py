"""Thread limits while mapping (issue 11): one BLAS thread, onnxruntime threads = cores // jobs."""

from __future__ import annotations

import os

import numpy as np
import pytest
from threadpoolctl import threadpool_info

from ltc_cli import threads
from ltc_cli.cli import cli


def blas_threads() -> list[int]:
    return [lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"]


def test_cores_is_the_affinity_mask():
    assert threads.cores() == len(os.sched_getaffinity(0))


@pytest.mark.parametrize("jobs", [1, 2, 3, 64])
def test_threads_per_job_divides_the_cores_among_the_jobs(jobs):
    import cv2

    n = len(os.sched_getaffinity(0))
    assert threads.threads_per_job() == n  # outside an ingest: every core
    cv_threads = cv2.getNumThreads()
    with threads.mapping_threads(jobs):
        assert threads.threads_per_job() == max(1, n // jobs)
        assert cv2.getNumThreads() == 1
        assert len(blas_threads()) >= 3 and set(blas_threads()) == {1}  # numpy's, scipy's and OpenCV's
        assert float(np.ones((64, 64)) @ np.ones(64) @ np.ones(64)) == 64.0 * 64  # BLAS still works
    assert threads.threads_per_job() == n
    assert cv2.getNumThreads() == cv_threads  # given back


def test_onnx_detector_threads_default_to_the_share_of_its_job(tmp_path):
    pytest.importorskip("onnx")
    from tests.test_onnx_detectors import YOLO_META, const_model, yolo_outputs
    from ltc_plugins.onnx.yolo_seg import YoloSegDetector

    model = const_model(tmp_path / "tiny-seg.onnx", ("images", [1, 3, 32, 32]), yolo_outputs(), YOLO_META)
    n = len(os.sched_getaffinity(0))
    assert YoloSegDetector.from_options(None, {"model": str(model)}).threads == n
    with threads.mapping_threads(2):
        assert YoloSegDetector.from_options(None, {"model": str(model)}).threads == max(1, n // 2)
        assert YoloSegDetector.from_options(None, {"model": str(model), "threads": 3}).threads == 3


def test_cli_main_holds_openblas_to_one_thread_unless_told(monkeypatch):
    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    monkeypatch.setattr(cli, "main", lambda **kw: None)
    from ltc_cli import cli as cli_module

    cli_module.main()
    assert os.environ["OPENBLAS_NUM_THREADS"] == "1"
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "4")
    cli_module.main()
    assert os.environ["OPENBLAS_NUM_THREADS"] == "4"

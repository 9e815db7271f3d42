"""A test plugin (loaded with LTC_PLUGINS): the recorded detector, with a gate at one frame for the
Dask worker-kill test. With LTC_TEST_GATE set to a folder and LTC_TEST_GATE_FRAME to a frame id,
the first process to detect that frame claims the gate (creates ``claimed`` there atomically),
writes its pid to ``ready`` (the signal the test waits for) and then waits to be killed; every
later attempt at that frame (the retry on another worker) goes through at once."""

import os
import threading
from pathlib import Path

from ltc_cli import hookimpl
from ltc_plugins.recorded import RecordedDetector


class Gate(RecordedDetector):
    def detect(self, frame):
        gate = os.environ.get("LTC_TEST_GATE")
        if gate and frame.key == os.environ.get("LTC_TEST_GATE_FRAME"):
            try:
                os.close(os.open(Path(gate) / "claimed", os.O_CREAT | os.O_EXCL | os.O_WRONLY))
            except FileExistsError:
                pass  # a retry: the first attempt's worker was killed
            else:
                tmp = Path(gate) / "ready.tmp"
                tmp.write_text(str(os.getpid()))
                tmp.rename(Path(gate) / "ready")
                threading.Event().wait(120)  # until the test kills this worker (bounded, should it not)
        return super().detect(frame)


@hookimpl
def register_detectors(register):
    register("gate-recorded", Gate.from_options)

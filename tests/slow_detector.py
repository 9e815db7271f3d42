"""A test plugin (loaded with LTC_PLUGINS): the recorded detector, slowed down, so that a test can
kill an ingest part-way. With LTC_TEST_READY set to a path, the first ``detect`` creates that file:
the ready signal a test waits for (the CLI's signal handlers are installed by then)."""

import os
import time
from pathlib import Path

from ltc_cli import hookimpl
from ltc_plugins.recorded import RecordedDetector


class Slow(RecordedDetector):
    def detect(self, frame):
        ready = os.environ.get("LTC_TEST_READY")
        if ready:
            Path(ready).touch()
        time.sleep(float(os.environ.get("LTC_TEST_DELAY", "0.2")))
        return super().detect(frame)


@hookimpl
def register_detectors(register):
    register("slow-recorded", Slow.from_options)

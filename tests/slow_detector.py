"""A test plugin (loaded with LTC_PLUGINS): the recorded detector, slowed down, so that a test can
kill an ingest part-way."""

import os
import time

from ltc_cli import hookimpl
from ltc_plugins.recorded import RecordedDetector


class Slow(RecordedDetector):
    def detect(self, frame):
        time.sleep(float(os.environ.get("LTC_TEST_DELAY", "0.2")))
        return super().detect(frame)


@hookimpl
def register_detectors(register):
    register("slow-recorded", Slow.from_options)

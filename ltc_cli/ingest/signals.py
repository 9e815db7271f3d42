"""Stopping an ingest cleanly on SIGINT / SIGTERM: the signal only asks the run to stop after its
current frame, so that it commits a whole map first (DESIGN.md section 4)."""

from __future__ import annotations

import signal
from contextlib import contextmanager


@contextmanager
def stop_on_signals():
    """SIGINT and SIGTERM ask a run to stop after its current frame (it commits, then returns); a
    second Ctrl-C stops at once. Yields {"signal": the first signal received, or None}."""
    stop = {"signal": None}

    def on_signal(signum, _frame):
        if stop["signal"] is not None and signum == signal.SIGINT:
            raise KeyboardInterrupt  # a second Ctrl-C: stop now (the map is still committed)
        stop["signal"] = signum

    old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield stop
    finally:
        for s, h in old.items():
            signal.signal(s, h)

"""Built-in maintenance policies: ``non-detection`` (the paper's) and ``static`` (never removes)."""

from __future__ import annotations

import numpy as np

from ltc_cli import hookimpl
from ltc_cli.pipeline.maintenance import other_leads


class NonDetectionPolicy:
    """An object in view, with enough pixels that the camera should have seen, that no detection
    matched, gets a non-detection (eq. 4); it is removed once `other` leads its class vector."""

    def __init__(self, options: dict):
        pass

    def non_detections(self, matched, visible_px, required_px):
        return ~np.asarray(matched, dtype=bool) & (np.asarray(visible_px) >= required_px)

    def removals(self, scores):
        return other_leads(scores)


class StaticPolicy:
    """The static-world assumption: nothing is ever removed (a baseline to compare against)."""

    removes = False  # nor by the session-level absence rule (maintenance.absent_after_views)

    def __init__(self, options: dict):
        pass

    def non_detections(self, matched, visible_px, required_px):
        return np.zeros(len(matched), dtype=bool)

    def removals(self, scores):
        return np.zeros(len(np.atleast_2d(scores)), dtype=bool)


@hookimpl
def register_policies(register):
    register("non-detection", NonDetectionPolicy)
    register("static", StaticPolicy)

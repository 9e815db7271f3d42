"""Built-in association metrics: ``vertex`` (the paper's eq. 2) and ``centroid`` (a baseline)."""

from __future__ import annotations

from ltc_cli import hookimpl
from ltc_cli.pipeline.association import centroid_distance, vertex_distance


class VertexMetric:
    """Eq. 2: mean distance of corresponding vertices (4 cyclic shifts), visible pairs only when
    at least ``min_visible_pairs`` of them are visible in both boxes."""

    # The mean distance of corners is at least the centres' distance less both half diagonals:
    # the mapper compares a detection only with the map objects that bound lets match.
    center_bound = True
    paired = True  # ``distance`` also takes M boxes paired with M candidates

    def __init__(self, options: dict):
        self.min_visible_pairs = int(options.get("min_visible_pairs", 3))

    def distance(self, det, cands):
        return vertex_distance(det, cands, self.min_visible_pairs)[0]


class CentroidMetric:
    """Baseline: distance between box centres. Blind to size and to which part a view saw, so a
    partial view of a long table lands far from the table's centre and makes a duplicate."""

    center_bound = True  # the distance is the centres' distance itself
    paired = True

    def __init__(self, options: dict):
        pass

    def distance(self, det, cands):
        return centroid_distance(det, cands)


@hookimpl
def register_metrics(register):
    register("vertex", VertexMetric)
    register("centroid", CentroidMetric)

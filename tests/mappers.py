"""A mapper over a map that already holds some objects, for tests of the steps after a frame."""

import numpy as np

from ltc_cli import plugins
from ltc_cli.map.model import ACTIVE, SemanticMap
from ltc_cli.geometry.camera import invert_pose
from ltc_cli.pipeline.mapper import Mapper
from tests.scene import INTR, T_world_camera


def mapper_with_boxes(classes: list, cfg: dict, centers, sizes, defined, scores, n_det) -> Mapper:
    """A session-0 mapper whose map holds one active object per row of the given lists: axis-aligned
    boxes (yaw 0) with every vertex visible, indexed for the frame's candidates."""
    smap = SemanticMap.new(classes)
    mapper = Mapper(smap, cfg, plugins.get("metrics", "vertex").factory(cfg["association"]),
                    plugins.get("policies", "non-detection").factory(cfg["maintenance"]))
    for center, size, whole, vector, n in zip(centers, sizes, defined, scores, n_det):
        center, size = np.array(center, dtype=float), np.array(size, dtype=float)
        row = smap.objects.append(center=center, yaw=0.0, size=size, visible=np.ones(8, bool), defined=whole,
                                  scores=np.array(vector, dtype=float), n_det=n, n_nondet=0, status=ACTIVE)
        mapper.index.insert(row, center, size)
    return mapper


def merge_seen_from_origin(mapper: Mapper) -> int:
    """The merge step after a frame from tests.scene's camera (at the origin, looking along +x, 6 m
    of depth): how many merges it made."""
    return mapper._merge_in_view(0, "f0", invert_pose(T_world_camera()), INTR, 6.0)

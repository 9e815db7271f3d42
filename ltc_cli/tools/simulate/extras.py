"""What the realistic profile adds to one lap beyond the house: the localiser's poses, the fixed
phantoms, the people walking through, the detector's view model and the depth sensor's dropout.
With every realism option off it adds nothing (and the lap is the benign one, byte for byte)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ltc_cli.tools.simulate.drift import estimated_poses
from ltc_cli.tools.simulate.house import House
from ltc_cli.tools.simulate.options import REALISM_DEFAULTS
from ltc_cli.tools.simulate.people import people_boxes, plan_walks
from ltc_cli.tools.simulate.sensor import dropout_map
from ltc_cli.tools.simulate.views import ViewModel

#: Classes whose surfaces (screens, steel, glass) a depth sensor often cannot read.
SHINY = ("tv", "refrigerator", "oven", "sink", "laptop")


def _stack(boxes):
    """Primitive arrays (centers, yaws, sizes, colours, owners) of boxes (center, yaw, size, colour,
    owner)."""
    c, y, s, col, own = zip(*boxes)
    return (np.array(c, dtype=np.float64), np.array(y, dtype=np.float64), np.array(s, dtype=np.float64),
            np.array(col, dtype=np.float64), np.array(own, dtype=np.int64))


def _concat(a, b):
    return tuple(np.concatenate([x, y]) for x, y in zip(a, b))


@dataclass
class LapExtras:
    written_poses: np.ndarray  # (F, 4, 4): what poses.txt says (the true poses, or a localiser's)
    phantoms: list
    walkers: list
    views: ViewModel | None
    shiny_ids: np.ndarray  # object ids whose surfaces are shiny
    opts: dict

    @classmethod
    def make(cls, house: House, poses: np.ndarray, phantoms: list, opts: dict, seed: int, lap: int) -> LapExtras:
        written = estimated_poses(poses, np.random.default_rng([seed, lap, 0x10CA1]), opts)
        walkers = plan_walks(house, poses, np.random.default_rng([seed, lap, 0x9E0]), opts["people_per_room"])
        views = None
        if any(opts[k] != v for k, v in REALISM_DEFAULTS.items()):
            # o.yaw, not the box's wrapped yaw: the object's front is its +x side.
            things = {oid: (o.cls, "object", o.box()[0], o.yaw) for oid, o in house.objects.items()}
            things.update({p.id: (p.cls, "phantom", p.center, p.yaw) for p in phantoms})
            things.update({w.id: ("person", "person", np.append(w.start, 0.0), 0.0) for w in walkers})
            views = ViewModel(opts, seed, lap, len(poses), things)
        shiny = np.array([oid for oid, o in house.objects.items() if o.cls in SHINY], dtype=np.int64)
        return cls(written, phantoms, walkers, views, shiny, opts)

    def classes_of(self) -> dict:
        """Detectable things that are not ground-truth objects: id -> class."""
        out = {p.id: p.cls for p in self.phantoms}
        out.update({w.id: "person" for w in self.walkers})
        return out

    def static_primitives(self, house: House):
        """The house's primitives and the phantoms' (owner = phantom id)."""
        prims = house.primitives()
        boxes = [(c, y, s, col, p.id) for p in self.phantoms for c, y, s, col in p.boxes]
        return _concat(prims, _stack(boxes)) if boxes else prims

    def frame_primitives(self, index: int, T_world_camera: np.ndarray, static):
        """The static primitives and the people in view at this frame."""
        boxes = people_boxes(self.walkers, index, T_world_camera)
        return _concat(static, _stack(boxes)) if boxes else static

    def dropout(self, prim: np.ndarray, prims):
        """The depth sensor's per-pixel probability of no reading (H, W), or None."""
        return dropout_map(prim, prims[3], np.isin(prims[4], self.shiny_ids), self.opts)

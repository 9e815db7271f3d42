"""What bench_real.py reports of a map: its objects per class and ids, what became of the ids a
revisit lost, and where the objects a revisit added stand against the map of every frame."""

from __future__ import annotations

from collections import Counter

import numpy as np

from ltc_cli.map.model import ACTIVE, top_class
from ltc_cli.map.store import load_map


def census(map_path) -> tuple[Counter, set]:
    smap = load_map(map_path)
    t = smap.objects
    rows = np.flatnonzero(t.status == ACTIVE)
    return Counter(smap.classes[int(c)] for c in top_class(t.scores[rows])), set((rows + 1).tolist())


def lost_ids(map_path, ids: set) -> list[str]:
    """What became of each session-1 id that the revisit lost: class, place and the event that ended
    it (so a lost id can be read as a wrong object cleaned up or a real one dropped)."""
    smap = load_map(map_path)
    t, out = smap.objects, []
    for oid in sorted(ids):
        r = oid - 1
        ends = [e for e in smap.events if e.session >= 1 and e.kind in ("removed", "merged")
                and (e.object_id == oid if e.kind == "removed" else e.other_id == oid)]
        how = (f"{ends[-1].kind} at frame {ends[-1].frame}" + (f" into {ends[-1].object_id}" if ends[-1].kind == "merged"
               else f" ({ends[-1].detail})")) if ends else "?"
        out.append(f"{smap.classes[int(top_class(t.scores[r]))]} {oid} at ({t.center[r][0]:.2f}, {t.center[r][1]:.2f}, "
                   f"{t.center[r][2]:.2f}), {int(t.n_det[r])} detections: {how}")
    return out


def new_objects(map_path, ids: set, full_map_path) -> list[str]:
    """Class, place and detections of each object a revisit added, and how far the nearest object
    of its class stands in the map of every frame (``full_map_path``): a thing the first session
    missed that the whole recording maps, or the detector's mistake."""
    smap, full = load_map(map_path), load_map(full_map_path)
    t, f = smap.objects, full.objects
    rows = np.flatnonzero(f.status == ACTIVE)
    out = []
    for oid in sorted(ids):
        r = oid - 1
        cls = smap.classes[int(top_class(t.scores[r]))]
        same = rows[[full.classes[int(c)] == cls for c in top_class(f.scores[rows])]]
        near = (f"the full recording's map has one {np.linalg.norm(f.center[same] - t.center[r], axis=1).min():.2f} m "
                f"away" if same.size else "none in the full recording's map")
        out.append(f"{cls} {oid} at ({t.center[r][0]:.2f}, {t.center[r][1]:.2f}, {t.center[r][2]:.2f}), "
                   f"{int(t.n_det[r])} detections; {near}")
    return out

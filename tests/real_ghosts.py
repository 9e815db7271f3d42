"""Things a real map holds that are no longer there, put into it by hand: the method's second
promise (no ghost of a thing that went) held to a real recording with the real detector, which
the simulator alone had shown (tests/test_real_ghosts.py, benchmarks/bench_real.py).

A map of one session of tum-fr1-rpy is edited as if the room had changed since it was made:

``GHOSTS``: boxes of things that stood where the recording shows none (a mug on the bare desk in
front of the keyboard; a monitor at the desk's front edge, over the game controller and the
trackball, which must keep their own boxes), each with the counts and class vector of the map's
most detected object of its class, as if as well established.

``MOVES``: things that stood elsewhere last time (the mug by the milk carton 0.3 m to its left, the
blue chair at the desk's left end): the box of the thing (the one of its class nearest its place
measured by hand, tests/real_truth.py) is moved there, so the map holds its old place and not its
present one.

A revisit with the same recording then has to remove every such box and keep every other id. Each
place is in the recording's world frame (a map's ``up_rotation`` takes it to the map frame). The mug's
old place holds the milk carton, which COCO has no class for: the depth shows something standing
there, so a session's silence alone does not remove it, two sessions' silence does
(``maintenance.absent_quiet_sessions``; a revisit of every frame sees through its box from above
and removes it in one).
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ltc_cli.map.changes import KINDS, map_changes
from ltc_cli.map.model import ACTIVE, Event, top_class
from ltc_cli.map.store import load_map, save_map
from ltc_cli.text import plural
from tests.real_truth import TUM_FR1_RPY, box_gaps


@dataclass(frozen=True)
class Ghost:
    name: str
    cls: str
    center_world: tuple[float, float, float]  # the box's middle, the recording's world frame
    size: tuple[float, float, float]  # along the map's x, y and z (yaw 0)


@dataclass(frozen=True)
class Move:
    name: str
    landmark: str  # the tests/real_truth.py place the thing's box holds
    old_world: tuple[float, float, float]  # where its box stood (its middle's x and y are taken)


GHOSTS = (
    Ghost("a mug in front of the keyboard", "cup", (0.971, 0.956, 0.814), (0.09, 0.09, 0.10)),
    Ghost("a monitor at the desk's front edge, over the game controller", "tv", (0.875, 0.271, 0.967),
          (0.15, 0.5, 0.45)),
)

MOVES = (
    Move("the mug, by the milk carton 0.3 m to its left", "white mug", (0.531, 0.385, 0.829)),
    Move("the blue chair, at the desk's left end", "blue office chair behind the desk", (0.514, -0.517, 0.542)),
)

PLANTED = "planted by tests/real_ghosts.py"


def plant(map_path, ghosts=GHOSTS, moves=MOVES) -> dict[str, int]:
    """Edit the map at ``map_path`` in place: append ``ghosts`` and move the boxes of ``moves``.
    {name: object id} of every box a revisit has to remove."""
    smap = load_map(map_path)
    t, up = smap.objects, smap.up_rotation
    active = t.status == ACTIVE
    top = top_class(t.scores)
    out = {}
    for g in ghosts:
        mine = np.flatnonzero(active & (top == smap.classes.index(g.cls)))
        template = int(mine[np.argmax(t.n_det[mine])])
        values = {name: np.copy(col[template]) for name, col in t.columns().items()}
        values.update(center=up @ np.asarray(g.center_world), yaw=0.0, size=np.asarray(g.size))
        row = t.append(**values)
        smap.events.append(Event(0, int(values["first_frame"]), "", "created", row + 1, 0, PLANTED))
        out[g.name] = row + 1
    places = {lm.name: lm for lm in TUM_FR1_RPY}
    for mv in moves:
        lm = places[mv.landmark]
        mine = np.flatnonzero(active & (top == smap.classes.index(lm.cls)))
        point = up @ np.asarray(lm.world_xyz)
        row = int(mine[np.argmin(box_gaps(point, t.center[mine], t.yaw[mine], t.size[mine]))])
        t.cols["center"][row, :2] = (up @ np.asarray(mv.old_world))[:2]
        out[mv.name] = row + 1
    save_map(smap, map_path)
    return out


def still_there(map_path, planted: dict[str, int]) -> list[str]:
    """The names of the planted or moved boxes still active in the map."""
    status = load_map(map_path, events=False).objects.status
    return [name for name, oid in planted.items() if status[oid - 1] == ACTIVE]


def active_ids(map_path) -> set[int]:
    return set((np.flatnonzero(load_map(map_path, events=False).objects.status == ACTIVE) + 1).tolist())


def ghost_lines(first_map, tmp, revisit, passes) -> list[str]:
    """benchmarks/bench_real.py's report: for each pass (label, [reader of each revisit]), a copy
    of the one-session map ``first_map`` planted (:func:`plant`) and revisited by
    ``revisit(map, reader)``: which boxes each revisit left, the other ids it lost, and what
    ``ltc changes`` reports against the planted map (session 0)."""
    out = [f"  ghosts put into the session-1 map (tests/real_ghosts.py: {len(GHOSTS)} things no longer there, "
           f"{len(MOVES)} moved):"]
    smap = load_map(first_map, events=False)
    top = top_class(smap.objects.scores[smap.active_rows()])
    held = {smap.classes[int(c)] for c in top}
    moved = {m.landmark for m in MOVES}
    missing = sorted(({g.cls for g in GHOSTS} | {lm.cls for lm in TUM_FR1_RPY if lm.name in moved}) - held)
    if missing:  # a setting under test lost the things the ghosts are made from
        return out[:1] + [f"    not planted: the session-1 map holds no {' and no '.join(missing)} to copy or move"]
    for k, (label, readers) in enumerate(passes):
        m = Path(tmp) / f"ghosts-{k}.h5"
        shutil.copyfile(first_map, m)
        before = active_ids(m)
        planted = plant(m)
        others = before - set(planted.values())
        steps = []
        for reader in readers:
            revisit(m, reader)
            left = still_there(m, planted)
            stays = f" ({'; '.join(left)} stays)" if left else ""
            steps.append(f"{len(planted) - len(left)} of {len(planted)} gone{stays}")
        lost = others - active_ids(m)
        rep = map_changes(load_map(m), since=0)
        moves = ", ".join(f"{c.cls} {c.distance:.2f} m" for c in rep.changes if c.kind == "moved")
        said = ", ".join(f"{rep.count(k)} {k}" for k in KINDS) + (f" ({moves})" if moves else "")
        out.append(f"    {label}: {' -> '.join(steps)}; other ids kept {len(others) - len(lost)} of {len(others)}; "
                   f"ltc changes: {said}")
    return out


def unchanged_lines(maps) -> list[str]:
    """benchmarks/bench_real.py's report on passes over a room that did not change: what
    ``ltc changes`` reports after each map's last session (maps of one session are skipped), and
    how many additions it counted as confirmed (an earlier session's glimpse) or as first seen
    (where no earlier session looked)."""
    reports = [(label, map_changes(smap)) for label, path in maps
               if len((smap := load_map(path)).sessions) > 1]
    if not reports:
        return []
    total = {k: sum(rep.count(k) for _, rep in reports) for k in KINDS}
    out = [f"  ltc changes after the {len(reports)} revisits above (the room did not change): "
           + ", ".join(f"{n} {k}" for k, n in total.items())
           + f"; {plural(sum(rep.confirmed for _, rep in reports), 'addition')} confirmed an earlier session's glimpse"
           + f"; {plural(sum(rep.first_seen for _, rep in reports), 'addition')} first seen where no earlier "
           "session looked"]
    return out + [f"    {label}: " + ", ".join(f"{c.kind} {c.cls} {c.object_id}" for c in rep.changes)
                  for label, rep in reports if rep.changes]

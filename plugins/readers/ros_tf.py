"""A TF tree from ``/tf`` and ``/tf_static``: transforms chained between any two frames and
interpolated in time, in numpy (no ROS, no tf2).

Each ``TransformStamped`` gives the pose of ``child_frame_id`` in ``header.frame_id`` (its parent):
``T_parent_child``. A frame has one parent (TF is a tree). The pose of frame ``b`` in frame ``a`` at
time t is the product of the edges from ``a`` up to their common ancestor (inverted) and from there
down to ``b``. A static edge holds at every time; a dynamic edge is interpolated between the two
stamps that bracket t (translation linearly, rotation by slerp), as tf2 does, when they are at most
``max_gap`` apart; t outside an edge's stamps is refused (tf2 does not extrapolate either) unless
within ``tolerance`` of the nearest stamp.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation, Slerp


class TfLookupError(ValueError):
    """No transform between two frames at a time (frames not connected, or time not covered)."""


@dataclass
class _Edge:
    """T_parent_child over time: stamps (N,) ns, translations (N, 3), quaternions (N, 4) xyzw."""

    static: bool = False
    stamps: list = field(default_factory=list)
    t: list = field(default_factory=list)
    q: list = field(default_factory=list)
    _arrays: tuple | None = None

    def arrays(self):
        if self._arrays is None:
            order = np.argsort(np.asarray(self.stamps, dtype=np.int64), kind="stable")
            self._arrays = (np.asarray(self.stamps, dtype=np.int64)[order], np.asarray(self.t)[order],
                            np.asarray(self.q)[order])
        return self._arrays


def transform(t_xyz, q_xyzw) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat(q_xyzw).as_matrix()
    T[:3, 3] = t_xyz
    return T


class TfTree:
    """Transforms added with :meth:`add`, looked up with :meth:`lookup`."""

    def __init__(self):
        self.edges: dict[str, _Edge] = {}  # child -> its edge
        self.parent: dict[str, str] = {}

    def add(self, parent: str, child: str, stamp_ns: int, t_xyz, q_xyzw, static: bool) -> None:
        """One transform (a later parent for a child replaces the earlier one, as in tf2)."""
        parent, child = parent.lstrip("/"), child.lstrip("/")
        q = np.asarray(q_xyzw, dtype=np.float64)
        norm = float(np.linalg.norm(q))
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(t_xyz)) and norm > 1e-6):
            return  # a broken transform is left out; lookups then say what is missing
        if self.parent.get(child) != parent or self.edges[child].static != static:
            self.edges[child] = _Edge(static=static)
            self.parent[child] = parent
        edge = self.edges[child]
        if edge.static:  # the latest static transform holds
            edge.stamps, edge.t, edge.q = [0], [np.asarray(t_xyz, float)], [q / norm]
        else:
            edge.stamps.append(int(stamp_ns))
            edge.t.append(np.asarray(t_xyz, float))
            edge.q.append(q / norm)
        edge._arrays = None

    @property
    def frames(self) -> set[str]:
        return set(self.parent) | set(self.parent.values())

    def chain(self, frame: str) -> list[str]:
        """``frame`` and its ancestors up to the root."""
        out = [frame]
        while out[-1] in self.parent and len(out) <= len(self.parent):
            out.append(self.parent[out[-1]])
        return out

    def root(self, frame: str) -> str:
        return self.chain(frame)[-1]

    def _edge_at(self, child: str, stamp_ns: int, max_gap_ns: int, tolerance_ns: int) -> np.ndarray:
        """T_parent_child at the time."""
        edge = self.edges[child]
        stamps, t, q = edge.arrays()
        if edge.static or len(stamps) == 1 and abs(stamp_ns - stamps[0]) <= tolerance_ns:
            return transform(t[0], q[0])
        k = int(np.searchsorted(stamps, stamp_ns))
        if k < len(stamps) and stamps[k] == stamp_ns:
            return transform(t[k], q[k])
        if 0 < k < len(stamps) and stamps[k] - stamps[k - 1] <= max_gap_ns:
            a = (stamp_ns - stamps[k - 1]) / (stamps[k] - stamps[k - 1])
            T = np.eye(4)
            T[:3, :3] = Slerp([0.0, 1.0], Rotation.from_quat(q[k - 1: k + 1]))(a).as_matrix()
            T[:3, 3] = (1 - a) * t[k - 1] + a * t[k]
            return T
        near = [j for j in (k - 1, k) if 0 <= j < len(stamps)]
        j = min(near, key=lambda j: abs(int(stamps[j]) - stamp_ns))
        if abs(int(stamps[j]) - stamp_ns) <= tolerance_ns:
            return transform(t[j], q[j])
        why = ("outside the times it covers" if k in (0, len(stamps)) else
               f"in a gap of {(stamps[k] - stamps[k - 1]) / 1e9:.3g} s")
        raise TfLookupError(
            f"no transform {self.parent[child]} -> {child} at {stamp_ns / 1e9:.3f} s ({why}: "
            f"{stamps[0] / 1e9:.3f} .. {stamps[-1] / 1e9:.3f} s)")

    def lookup(self, target: str, source: str, stamp_ns: int, max_gap_ns: int, tolerance_ns: int = 0) -> np.ndarray:
        """T_target_source (4, 4): the pose of frame ``source`` in frame ``target`` at the time."""
        up_s, up_t = self.chain(source), self.chain(target)
        common = next((f for f in up_s if f in set(up_t)), None)
        if common is None:
            raise TfLookupError(f"frames {target!r} and {source!r} are not connected by tf "
                                f"(their roots are {up_t[-1]!r} and {up_s[-1]!r})")

        def down(chain: list[str]) -> np.ndarray:
            """T_common_frame for chain[0], from the edges below the common ancestor."""
            T = np.eye(4)
            for child in chain[: chain.index(common)]:
                T = self._edge_at(child, stamp_ns, max_gap_ns, tolerance_ns) @ T
            return T

        return np.linalg.inv(down(up_t)) @ down(up_s)

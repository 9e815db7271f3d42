"""Clustering of back-projected mask points: the largest DBSCAN cluster of each detection, with
the clusters stacked on or under it (:func:`stacked_components`, ``modeling.stack_gap``).

Exact DBSCAN (scikit-learn's semantics, on a KD-tree) is the reference; the default grid DBSCAN
and voxel components are the fast equivalents (DESIGN.md 1.1, measured in docs/decisions.md).

Time and memory stay linear in the number of points however many detections a frame has: the
grid methods pack a detection's id into a cell key and take at most ``GROUPS_PER_PASS`` detections
and ``POINTS_PER_PASS`` points per pass (detections never share a cluster, so the passes give the
one-pass result), and exact
DBSCAN runs per detection on its own points. A frame with 3,000 detections once fell back to a
KD-tree over all its points (``query_pairs``: 18 GB, docs/reliability.md).
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ltc_cli.geometry.boxes import fit_box


# Half of the 26-neighbourhood: each undirected voxel adjacency is found once.
_HALF_NEIGHBOURS = np.array(
    [
        (dx, dy, dz)
        for dx in (-1, 0, 1)
        for dy in (-1, 0, 1)
        for dz in (-1, 0, 1)
        if (dx, dy, dz) > (0, 0, 0)
    ]
)


def voxel_components(points_xyz: np.ndarray, group: np.ndarray, eps: float):
    """Connected components of occupied voxels of size eps, never joining different groups.

    DBSCAN with min_samples = 1 on grid neighbours: two points are linked when their voxels touch
    (26-neighbourhood). Any two points closer than eps are in touching voxels, so every DBSCAN
    (min_samples = 1) cluster lies inside one component. Returns labels (N,) int.
    """
    n = len(points_xyz)
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    packed = _packed_cells(points_xyz, group, eps, 1)
    if packed is None:
        return _in_parts(voxel_components, points_xyz, group, eps, eps)
    keys, strides = packed
    uniq, inverse = np.unique(keys, return_inverse=True)
    offsets = _HALF_NEIGHBOURS @ strides
    rows, cols = [], []
    for off in offsets:
        target = uniq + off
        pos = np.searchsorted(uniq, target)
        pos_c = np.minimum(pos, len(uniq) - 1)
        hit = uniq[pos_c] == target
        rows.append(np.flatnonzero(hit))
        cols.append(pos_c[hit])
    r = np.concatenate(rows)
    c = np.concatenate(cols)
    m = len(uniq)
    graph = coo_matrix((np.ones(len(r), dtype=np.int8), (r, c)), shape=(m, m))
    _, vox_labels = connected_components(graph, directed=False)
    return vox_labels[inverse.ravel()]


def grid_dbscan_labels(points_xyz: np.ndarray, group: np.ndarray, eps: float, min_samples: float,
                       weights: np.ndarray | None = None) -> np.ndarray:
    """DBSCAN on a grid of cells of side eps / 2, all groups at once: labels (N,), -1 for noise.

    A cell's density is the number of points in it and its 26 neighbours (a 1.5 eps cube, about the
    volume of DBSCAN's eps-ball); cells with at least min_samples are core. Core cells whose
    distance can be under eps (up to 2 cells apart) are linked; a non-core cell next to a core one
    is a border cell of its cluster; the rest is noise. Like DBSCAN, sparse "flying pixels" between
    an object and the wall do not bridge them, at the cost of one sort and a few searchsorted
    calls instead of a neighbour search per point. weights (N,): what each point counts for in a
    density (None: 1 each).
    """
    n = len(points_xyz)
    labels = np.full(n, -1, dtype=np.int64)
    if n == 0:
        return labels
    packed = _packed_cells(points_xyz, group, eps / 2, 2)
    if packed is None:
        return _in_parts(grid_dbscan_labels, points_xyz, group, eps, eps, min_samples, weights=weights)
    keys, strides = packed
    uniq, inverse, counts = np.unique(keys, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    if weights is not None:
        counts = np.bincount(inverse, weights=weights, minlength=len(uniq))
    m = len(uniq)
    rows, cols = [], []
    for off in _OFFSETS_2 @ strides:
        target = uniq + off
        pos = np.minimum(np.searchsorted(uniq, target), m - 1)
        hit = np.flatnonzero(uniq[pos] == target)
        rows.append(hit)
        cols.append(pos[hit])
    r, c = np.concatenate(rows), np.concatenate(cols)
    nb = np.repeat(_NEAR_2, [len(h) for h in rows])  # the pair's cells touch (26-neighbourhood)
    density = (counts + np.bincount(r[nb], weights=counts[c[nb]], minlength=m)
               + np.bincount(c[nb], weights=counts[r[nb]], minlength=m))
    core = density >= min_samples
    cc = core[r] & core[c]
    graph = coo_matrix((np.ones(int(cc.sum()), dtype=np.int8), (r[cc], c[cc])), shape=(m, m))
    _, comp = connected_components(graph, directed=False)
    cell_label = np.where(core, comp, -1)
    # Border cells: next to a core cell (26-neighbourhood), they join its cluster.
    for a, b in ((r, c), (c, r)):
        sel = nb & core[a] & ~core[b]
        tgt = b[sel]
        unset = cell_label[tgt] == -1
        cell_label[tgt[unset]] = comp[a[sel][unset]]
    return cell_label[inverse]


# Detections clustered in one pass of the grid methods: the id goes into the top bits of a key.
GROUPS_PER_PASS = 1 << 10
# ... and at most this many points (about 90 MB of neighbour pairs): more are split into passes.
POINTS_PER_PASS = 1 << 17
_AXIS_BITS = 17


def _compact_axes(ijk: np.ndarray, reach: int) -> np.ndarray:
    """Cell indices (N, 3) with every empty stretch along an axis shortened to reach + 1 cells.

    Cells up to ``reach`` apart keep their distance and cells further apart stay further than
    ``reach``, so every neighbour relation, and the order of cells, is unchanged: a wide but sparse
    cloud (kilometres between points) still fits in packed keys.
    """
    out = np.empty_like(ijk)
    for a in range(3):
        uniq, inverse = np.unique(ijk[:, a], return_inverse=True)
        steps = np.minimum(np.diff(uniq), reach + 1)
        out[:, a] = np.concatenate([[0], np.cumsum(steps)])[inverse.ravel()]
    return out


def _packed_cells(points_xyz, group, cell, reach):
    """(keys (N,), strides (3,)): each point's (group, i, j, k) cell of side ``cell`` packed in an
    int64 whose fields a neighbour offset of up to ``reach`` cells never carries across; None when
    the groups or the extent do not fit (the caller splits the groups)."""
    if int(group.max()) >= GROUPS_PER_PASS or (len(points_xyz) > POINTS_PER_PASS and (group != group[0]).any()):
        return None
    ijk = np.floor(points_xyz / cell).astype(np.int64)
    ijk -= ijk.min(axis=0) - reach  # >= reach, so a -reach offset never borrows from another field
    if int(ijk.max()) + reach + 1 >= 1 << _AXIS_BITS:
        ijk = _compact_axes(ijk, reach) + reach
        if int(ijk.max()) + reach + 1 >= 1 << _AXIS_BITS:
            return None
    bx, by = np.int64(1) << np.int64(2 * _AXIS_BITS), np.int64(1) << np.int64(_AXIS_BITS)
    keys = (group.astype(np.int64) << np.int64(3 * _AXIS_BITS)) + ijk[:, 0] * bx + ijk[:, 1] * by + ijk[:, 2]
    return keys, np.array([bx, by, 1], dtype=np.int64)


def _in_parts(fn, points_xyz, group, eps, *args, weights=None):
    """Labels (N,) of ``fn(points, group, *args)`` run on parts of the groups: consecutive groups,
    at most GROUPS_PER_PASS of them and (unless one group alone) POINTS_PER_PASS points a part, so
    memory is bounded per part; a part within both that is still too wide for packed keys is
    halved.

    Groups never share a cluster and each part's labels are offset past the previous part's, so
    the labels (and their order) are those one pass would give. A single group too wide even for
    compacted keys (tens of thousands of distinct cells along an axis) falls back to exact
    neighbour components on its own points.
    """
    n_groups = int(group.max()) + 1
    sizes = np.bincount(group, minlength=n_groups)
    if np.count_nonzero(sizes) == 1:
        return _tree_components(points_xyz, group, eps)
    if n_groups <= GROUPS_PER_PASS and len(points_xyz) <= POINTS_PER_PASS:
        cuts = [0, n_groups // 2, n_groups]
    else:
        cuts, total = [0], 0
        for g, size in enumerate(sizes.tolist()):
            if g > cuts[-1] and (g - cuts[-1] >= GROUPS_PER_PASS or total + size > POINTS_PER_PASS):
                cuts.append(g)
                total = 0
            total += size
        cuts.append(n_groups)
    members = _members(group, n_groups)
    labels = np.full(len(points_xyz), -1, dtype=np.int64)
    offset = 0
    for g0, g1 in zip(cuts[:-1], cuts[1:]):
        idx = members(g0, g1)
        if not len(idx):
            continue
        part = fn(points_xyz[idx], group[idx] - g0, *args,
                  **({} if weights is None else {"weights": weights[idx]}))
        found = part >= 0
        labels[idx[found]] = part[found] + offset
        offset += int(part.max()) + 1 if found.any() else 0
    return labels


def _members(values: np.ndarray, n: int):
    """members(v) -> the indices i with values[i] == v, in increasing order, for v in 0..n-1
    (members(v, w): those with v <= values[i] < w, by value), from one stable sort: a scan per
    value is quadratic in the number of detections."""
    order = np.argsort(values, kind="stable")
    bounds = np.searchsorted(values[order], np.arange(n + 1))
    return lambda v, w=None: order[bounds[v]:bounds[v + 1 if w is None else w]]


def _tree_components(points_xyz, group, eps):
    tree = cKDTree(points_xyz)
    pairs = tree.query_pairs(eps, output_type="ndarray")
    pairs = pairs[group[pairs[:, 0]] == group[pairs[:, 1]]]
    n = len(points_xyz)
    graph = coo_matrix((np.ones(len(pairs), dtype=np.int8), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    return connected_components(graph, directed=False)[1]


def dbscan_labels(points_xyz: np.ndarray, eps: float, min_samples: float, weights: np.ndarray | None = None) -> np.ndarray:
    """Exact DBSCAN (Ester et al. 1996), by scikit-learn: labels (N,), -1 for noise.

    Core points have at least min_samples points (themselves included) within eps; clusters are the
    connected components of core points; a border point joins the cluster of a core neighbour
    (with ``weights`` (N,), the points' summed weights count instead: scikit-learn's
    sample_weight). The reference that the grid clustering (the default) is measured and tested
    against.
    """
    if len(points_xyz) == 0:
        return np.zeros(0, dtype=np.int64)
    from sklearn.cluster import DBSCAN  # imported here: only the exact mode and the tests need it

    fit = DBSCAN(eps=eps, min_samples=min_samples, algorithm="kd_tree").fit(points_xyz, sample_weight=weights)
    return fit.labels_.astype(np.int64)


def largest_clusters(points_xyz, group, eps, min_samples, method="voxel", stack_gap=None, weights=None):
    """For each group (detection), the indices of its largest cluster, or None if too small; with
    ``stack_gap`` (metres), joined by the clusters that are parts of the same object
    (:func:`stacked_components`). weights (N,): what each point counts for, in DBSCAN's densities
    and in cluster sizes (a subsampled mask point stands for the pixels around it; None: 1 each).

    ``voxel``: voxel components over all groups at once, then components with fewer than
    min_samples points are noise. ``dbscan``: exact DBSCAN per group. Returns a list indexed by
    group id.
    """
    n_groups = int(group.max()) + 1 if len(group) else 0
    out: list = [None] * n_groups
    if method == "dbscan":
        members = _members(group, n_groups)
        for g in range(n_groups):
            idx = members(g)
            w = None if weights is None else weights[idx]
            labels = dbscan_labels(points_xyz[idx], eps, min_samples, w)
            if (labels >= 0).any():
                counts = np.bincount(labels[labels >= 0], weights=None if w is None else w[labels >= 0])
                best = int(counts.argmax())
                parts = [best]
                if stack_gap is not None:
                    inl = labels >= 0
                    parts = stacked_components(points_xyz[idx][inl], labels[inl], np.zeros(len(counts), np.int64),
                                               counts, min_samples, stack_gap, eps).get(best, [best])
                out[g] = idx[np.isin(labels, parts)]
        return out
    if method == "grid":
        labels = grid_dbscan_labels(points_xyz, group, eps, min_samples, weights)
        keep = labels >= 0
        if not keep.any():
            return out
        points_idx = np.flatnonzero(keep)
        labels, group = labels[keep], group[keep]
    else:
        points_idx = np.arange(len(points_xyz))
        labels = voxel_components(points_xyz, group, eps)
    counts = np.bincount(labels, weights=None if weights is None else weights[points_idx])
    # The largest component of each group: sort by (group, -count) and take the first per group.
    comp_group = np.zeros(len(counts), dtype=np.int64)
    comp_group[labels] = group
    order = np.lexsort((-counts, comp_group))
    first = order[np.r_[True, comp_group[order][1:] != comp_group[order][:-1]]]
    members = _members(labels, len(counts))
    stacked = None
    if stack_gap is not None:
        stacked = stacked_components(points_xyz[points_idx], labels, comp_group, counts, min_samples, stack_gap, eps)
    for comp in first:
        if counts[comp] >= min_samples:
            parts = [comp] if stacked is None else stacked.get(int(comp), [comp])
            out[int(comp_group[comp])] = np.sort(np.concatenate([points_idx[members(c)] for c in parts]))
    return out


def stacked_components(points_xyz, labels, comp_group, counts, min_samples, max_gap, margin=0.0) -> dict:
    """{largest component: it and the components that are parts of the same object} for each
    group with more than one component of at least min_samples points.

    A mask can join what the points do not: a plant's pot and foliage when the thin stem gives no
    depth, the far part of a table top beyond a gap in the readings. A component is such a part
    when at least half of its points lie within ``margin`` metres (the clustering's eps) of the
    footprint of the object so far (the minimum-area rectangle, on the XY plane, of the parts
    kept) and the vertical gap between them is at most ``max_gap`` metres. A patch of wall or
    floor that the mask bled onto lies beside the object or far below it, so the largest cluster
    still sheds it. Parts join one at a time, the largest first, each against the footprint grown
    by the ones before.
    """
    big = counts >= min_samples
    if not big.any():
        return {}
    per_group = np.bincount(comp_group[big], minlength=int(comp_group.max()) + 1)
    if not (per_group >= 2).any():
        return {}
    members = _members(labels, len(counts))
    out = {}
    for g in np.flatnonzero(per_group >= 2):
        comps = np.flatnonzero(big & (comp_group == g))
        comps = [int(c) for c in comps[np.argsort(-counts[comps], kind="stable")]]
        kept = [comps[0]]
        grew = True
        while grew:
            grew = False
            pts = points_xyz[np.concatenate([members(c) for c in kept])]
            center, yaw, size = fit_box(pts)
            for c in comps:
                if c in kept:
                    continue
                p = points_xyz[members(c)]
                d = p[:, :2] - center[:2]
                u = d[:, 0] * np.cos(yaw) + d[:, 1] * np.sin(yaw)
                v = -d[:, 0] * np.sin(yaw) + d[:, 1] * np.cos(yaw)
                inside = np.mean((np.abs(u) <= size[0] / 2 + margin) & (np.abs(v) <= size[1] / 2 + margin))
                gap = max(p[:, 2].min() - pts[:, 2].max(), pts[:, 2].min() - p[:, 2].max())
                if inside >= 0.5 and gap <= max_gap:
                    kept.append(c)
                    grew = True
                    break  # the footprint grew: measure the rest against the new one
        out[kept[0]] = kept
    return out


_OFFSETS_2 = np.array(
    [(dx, dy, dz) for dx in range(-2, 3) for dy in range(-2, 3) for dz in range(-2, 3) if (dx, dy, dz) > (0, 0, 0)]
)


_NEAR_2 = np.abs(_OFFSETS_2).max(axis=1) <= 1

"""The recorded detector: a noisy instance segmentation made from the true visible instances.

Masks come from the true visible instance image (so occlusion and image borders give partial masks
by themselves); objects with too few visible pixels are not detected; a detection is missed with
probability ``miss_rate`` scaled up for small, far and partly hidden objects; its class is swapped
for a similar one (chair <-> couch, cup <-> bowl, book <-> laptop, ...) with probability
``confusion_rate``; masks are dilated by about ``bleed_px`` pixels onto their neighbours; a mask is
sometimes split in two (over-segmentation); false positives are blobs on walls and floors with a
random class. Scores lie in about [0.5, 0.99].
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from ltc_cli.tools.simulate.options import CONFUSABLE
from ltc_cli.tools.simulate.views import CONFUSION, MISS

def detect(rng, inst, depth_m, stats, classes_of, classes, opts, min_pixels, views=None):
    """Instances of one frame from the true visible instance image inst (H, W) (object id, 0 none).

    depth_m (H, W): the depth written (metres, 0 = none); stats: per object id, its unoccluded
    pixel count and unclipped projected bounds (from the renderer); classes_of: object id -> class.
    views: None (every miss and confusion independent, one miss rate for every class), or a
    views.FrameViews (the realistic failure modes; rng's draws stay the same either way).
    Returns a list of (class, score, {class: score}, mask (H, W) bool), sorted by score.
    """
    H, W = inst.shape
    out = []
    ids, counts = np.unique(inst[inst > 0], return_counts=True)
    cross = ndimage.generate_binary_structure(2, 1)
    for oid, n in zip(ids.tolist(), counts.tolist()):
        if n < min_pixels:
            continue
        full_n, (bu0, bu1, bv0, bv1) = stats.get(oid, (n, (0, W, 0, H)))
        area = max(1e-9, (bu1 - bu0) * (bv1 - bv0))
        in_img = max(0.0, min(bu1, W) - max(bu0, 0)) * max(0.0, min(bv1, H) - max(bv0, 0))
        visible_frac = min(1.0, n / max(full_n, 1)) * min(1.0, in_img / area)
        mask = inst == oid
        z = depth_m[mask]
        z = z[z > 0]
        dist = float(np.median(z)) if z.size else opts["max_range"]
        far = min(1.0, max(0.0, (dist - 3.0) / 3.0))
        small = min(1.0, max(0.0, 1.0 - n / (10.0 * min_pixels)))
        # The base rate, up to 3x for a mostly hidden or cut object, 2.5x beyond 6 m, 3x near the
        # pixel minimum; miss_rate 0 is a detector that never misses.
        p_miss = opts["miss_rate"] * (1 + 2.0 * (1 - visible_frac) + 1.5 * far + 2.0 * small)
        u = rng.uniform()
        if views is not None:
            p_miss, u = views.miss_probability(oid, p_miss), views.uniform(oid, u, MISS)
        if u < min(0.97, p_miss):
            continue
        true_cls = classes_of[oid]
        cls = true_cls
        partner = CONFUSABLE.get(true_cls, ())
        u = rng.uniform()
        if views is not None:
            u = views.uniform(oid, u, CONFUSION)
        if u < opts["confusion_rate"] * (1 + (1 - visible_frac)):
            cls = partner[int(rng.integers(len(partner)))] if partner else classes[int(rng.integers(len(classes)))]
        alt = None if views is None else views.systematic_label(oid)
        cls = alt or cls
        score = float(rng.uniform(0.62, 0.99)) - 0.2 * (1 - visible_frac) - 0.08 * small
        if cls != true_cls:
            score -= 0.08
        score = float(np.clip(score, 0.5, 0.99))
        second = true_cls if cls != true_cls else (partner[0] if partner else None)
        scores = {cls: score}
        if second is not None and second != cls:
            scores[second] = (1 - score) * float(rng.uniform(0.3, 0.9))
        # Bleed: dilate onto the neighbours (on a crop around the object, for speed).
        k = max(0, int(opts["bleed_px"]) + int(rng.integers(-1, 2))) if opts["bleed_px"] > 0 else 0
        if k:
            vs, us = np.nonzero(mask)
            v0, v1 = max(0, vs.min() - k), min(H, vs.max() + k + 1)
            u0, u1 = max(0, us.min() - k), min(W, us.max() + k + 1)
            grown = ndimage.binary_dilation(mask[v0:v1, u0:u1], structure=cross, iterations=k)
            mask = np.zeros((H, W), dtype=bool)
            mask[v0:v1, u0:u1] = grown
        if views is not None:
            mask = views.shape_mask(mask)
        masks = [mask]
        if n > 4 * min_pixels and rng.uniform() < opts["split_rate"]:
            # Over-segmentation: the mask cut in two across its longer side.
            vs, us = np.nonzero(mask)
            if np.ptp(us) >= np.ptp(vs):
                cut = int(np.median(us))
                a = mask.copy()
                a[:, cut:] = False
            else:
                cut = int(np.median(vs))
                a = mask.copy()
                a[cut:, :] = False
            masks = [a, mask & ~a]
        for m in masks:
            if m.any():
                out.append((cls, score, scores, m))
    if rng.uniform() < opts["false_positive_rate"]:
        # A blob on a wall or the floor, with any class.
        bg = (inst == 0) & (depth_m > 0)
        vs, us = np.nonzero(bg)
        if vs.size:
            j = int(rng.integers(vs.size))
            scale = W / 640.0
            rv, ru = rng.uniform(15, 60, 2) * scale
            vv, uu = np.ogrid[:H, :W]
            blob = (((vv - vs[j]) / rv) ** 2 + ((uu - us[j]) / ru) ** 2 <= 1.0) & bg
            if blob.sum() >= min_pixels:
                cls = classes[int(rng.integers(len(classes)))]
                score = float(rng.uniform(0.5, 0.75))
                out.append((cls, score, {cls: score}, blob))
    out.sort(key=lambda d: -d[1])
    return out

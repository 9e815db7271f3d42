"""CPU per call of ``convex_intersection_area`` (the footprint clipping under every overlap test
of the four stages) on P pairs of rectangles, through its two paths: plain floats, one pair after
another, and numpy, all pairs at once. The plain path serves calls of up to
``ltc_cli.geometry.polygons.FEW_PAIRS`` pairs; this prints where the two cross.

    python benchmarks/bench_polygons.py [--pairs 1,2,4,8,16,24,32,64] [--seconds 0.5]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numpy as np  # noqa: E402

from ltc_cli.geometry import polygons  # noqa: E402
from ltc_cli.geometry.boxes import box_corners  # noqa: E402


def cpu_ms(foot_a, foot_b, few: int, seconds: float) -> float:
    """CPU ms per call with ``FEW_PAIRS`` set to ``few`` (restored afterwards)."""
    saved = polygons.FEW_PAIRS
    polygons.FEW_PAIRS = few
    try:
        t0, calls = time.process_time(), 0
        while time.process_time() - t0 < seconds:
            polygons.convex_intersection_area(foot_a, foot_b)
            calls += 1
        return (time.process_time() - t0) / calls * 1e3
    finally:
        polygons.FEW_PAIRS = saved


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pairs", default="1,2,4,8,16,24,32,64")
    ap.add_argument("--seconds", type=float, default=0.5, help="CPU time per figure")
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    print(f"convex_intersection_area, CPU ms per call (FEW_PAIRS = {polygons.FEW_PAIRS})")
    print(" pairs  plain floats   numpy   floats / numpy")
    for p in (int(x) for x in args.pairs.split(",")):
        # Overlapping rectangles of furniture size, turned at random (every pair is clipped).
        center, yaw = rng.uniform(-0.3, 0.3, (2, p, 3)), rng.uniform(-np.pi, np.pi, (2, p))
        size = rng.uniform(0.2, 1.0, (2, p, 3))
        foot_a = box_corners(center[0], yaw[0], size[0])[:, :4, :2]
        foot_b = box_corners(center[1], yaw[1], size[1])[:, :4, :2]
        plain, vectorised = cpu_ms(foot_a, foot_b, p, args.seconds), cpu_ms(foot_a, foot_b, 0, args.seconds)
        print(f"{p:6d}  {plain:12.3f}  {vectorised:6.3f}   {plain / vectorised:6.2f}")


if __name__ == "__main__":
    main()

"""Commands on big maps (issue 11), in one run: CPU seconds and peak memory (max RSS) of

1. ``ltc export`` of a 100,000-object map (tests/sample_maps.big_map) as JSON and as WGS84 GeoJSON
   to a file, and ``ltc render --recording`` of it into four frames of the sample recording;
2. ``ltc query MAP --id 5``, ``ltc info MAP`` and ``ltc query MAP --removed`` on a map with 1.5M
   events (20,000 objects, built here with the library);

each a child process measured on its own (os.wait4); and

3. checkpoints (commits) on maps of 15k, 150k and 1.5M events: a whole rewrite (``save_map(...,
   in_place=False)``, every commit before issue 11) against 20 checkpoints in place (each adding
   1,000 events, 30 frame keys, 5 objects, changing 50 objects and the session row, about what 30
   frames of a real ingest add), CPU and wall seconds per commit and the file's size after them;
   each size in a child process of its own. ``--baseline CMD`` runs the same commands
with another ltc too (e.g. an older commit unpacked by ``git archive``:
``--baseline "env PYTHONPATH=/tmp/old python -c 'from ltc_cli.cli import main; main()'"``), so
before and after meet the same machine load. The cost of a lap into a 100k-object map (the grid
index built at a session's start) is in bench_pipeline.py.

    python benchmarks/bench_scale.py [--keep DIR] [--events 1500000] [--baseline CMD] [--commits-only]
"""

from __future__ import annotations

import argparse
import os
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
LTC = [sys.executable, "-c", "import sys; sys.argv[0] = 'ltc'; from ltc_cli.cli import main; main()"]


def measure(cmd: list[str]) -> tuple[float, float, float]:
    """(CPU s, wall s, max RSS MiB) of one child process; raises if it fails."""
    t0 = time.perf_counter()
    # Run outside the checkout: "python -c" puts the working folder first on sys.path.
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, cwd=tempfile.gettempdir())
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    err = proc.stderr.read().decode()
    proc.stderr.close()
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise SystemExit(f"{shlex.join(cmd)} failed:\n{err}")
    return usage.ru_utime + usage.ru_stime, wall, usage.ru_maxrss / 1024


def big_object_map(path: Path) -> None:
    from ltc_cli.map.store import save_map
    from tests.sample_maps import big_map

    save_map(big_map(100_000), path)


def big_event_map(path: Path, n_events: int) -> None:
    """20,000 objects and n_events events (created, updated, non-detection, a few removed) over
    150 sessions' frames, as a long-lived map's log grows."""
    from ltc_cli.map.model import REMOVED, Event
    from ltc_cli.map.store import save_map
    from tests.sample_maps import big_map

    smap = big_map(20_000, seed=2)
    rng = np.random.default_rng(3)
    kinds = np.array(["updated", "non-detection", "created", "merged"])
    k = kinds[np.minimum(rng.geometric(0.6, n_events) - 1, 3)]
    frame = np.sort(rng.integers(0, 1000 * 150, n_events))
    oid = rng.integers(1, 20_001, n_events)
    smap.events = [Event(int(f // 1000), int(f % 1000), f"lap{f // 1000:03d}/{f % 1000:06d}", str(kd), int(o))
                   for f, kd, o in zip(frame.tolist(), k, oid.tolist())]
    removed = np.flatnonzero(smap.objects.status == REMOVED) + 1
    smap.events += [Event(149, 999, "lap149/000999", "removed", int(o), 0, "other leads") for o in removed]
    smap.frame_keys = {f"lap{s:03d}/{f:06d}" for s in range(150) for f in range(0, 1000, 50)}
    save_map(smap, path)


def checkpoint_delta(smap, rng, step: int) -> None:
    """About what 30 frames of an ingest add to a map: events, frame keys, a few objects."""
    from ltc_cli.map.model import Event

    n = smap.objects.n
    rows = rng.integers(0, n, 50)
    smap.objects.cols["center"][rows] += 0.01
    smap.objects.cols["n_det"][rows] += 1
    for _ in range(5):
        smap.objects.append(center=rng.normal(size=3), yaw=0.1, size=[1, 1, 1], visible=[True] * 8, defined=True,
                            scores=rng.dirichlet(np.ones(len(smap.classes) + 1)), n_det=1)
    oid = rng.integers(1, smap.objects.n + 1, 1000)
    smap.events += [Event(150, step * 30 + i // 34, f"lap150/{step * 30 + i // 34:06d}", "updated", int(o))
                    for i, o in enumerate(oid.tolist())]
    smap.frame_keys |= {f"lap150/{step * 30 + i:06d}" for i in range(30)}
    smap.sessions[-1]["frames_done"] = step * 30


def commit_child(path: Path, checkpoints: int) -> None:
    """Print one line: whole-rewrite and in-place commit times (CPU, wall) and sizes."""
    from ltc_cli.map.store import load_map, save_map

    rng = np.random.default_rng(5)
    smap = load_map(path)
    smap.sessions.append(dict(smap.sessions[-1], status="interrupted", frames_done=0))

    def timed(**kw):
        c0, w0 = time.process_time(), time.perf_counter()
        save_map(smap, path, **kw)
        return time.process_time() - c0, time.perf_counter() - w0

    whole = [timed(in_place=False) for _ in range(3)]  # before: every commit wrote the whole file
    size0 = path.stat().st_size
    inplace = []
    for step in range(1, checkpoints + 1):
        checkpoint_delta(smap, rng, step)
        inplace.append(timed())
    grown = (path.stat().st_size - size0) / 1e6
    w_cpu, w_wall = np.median(whole, axis=0)
    i_cpu, i_wall = np.median(inplace, axis=0)
    n = len(smap.events) - checkpoints * 1000
    print(f"checkpoint, {n:>9,} events  whole {w_cpu:6.3f} s CPU {w_wall:6.3f} s wall"
          f" | in place {i_cpu:6.3f} s CPU {i_wall:6.3f} s wall (median of {checkpoints}); file {size0 / 1e6:6.1f} MB,"
          f" +{grown:.2f} MB after {checkpoints} checkpoints of +1,000 events")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--keep", type=Path, help="folder to keep (and reuse) the built maps in")
    ap.add_argument("--events", type=int, default=1_500_000)
    ap.add_argument("--baseline", help="another ltc command line to measure with")
    ap.add_argument("--build-only", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--commit-child", type=Path, help=argparse.SUPPRESS)
    ap.add_argument("--commits-only", action="store_true", help="only the checkpoint figures")
    ap.add_argument("--checkpoints", type=int, default=20)
    args = ap.parse_args()
    if args.commit_child:
        commit_child(args.commit_child, args.checkpoints)
        return
    tmp = args.keep or Path(tempfile.mkdtemp(prefix="ltc-scale-"))
    tmp.mkdir(parents=True, exist_ok=True)
    objects_map, events_map = tmp / "objects-100k.h5", tmp / f"events-{args.events}.h5"
    commit_sizes = [15_000, 150_000, 1_500_000]
    if args.build_only:
        if not objects_map.exists() and not args.commits_only:
            big_object_map(objects_map)
        for n in ([] if args.commits_only else [args.events]) + commit_sizes:
            if not (tmp / f"events-{n}.h5").exists():
                big_event_map(tmp / f"events-{n}.h5", n)
        return
    # Built in a child: a child forked from a big parent would report the parent's peak memory.
    subprocess.run([sys.executable, __file__, "--build-only", "--keep", str(tmp), "--events", str(args.events)]
                   + ["--commits-only"] * args.commits_only, check=True)
    print(f"maps in {tmp}")
    for n in commit_sizes:  # on a copy: the commits change it
        shutil.copyfile(tmp / f"events-{n}.h5", tmp / "commits.h5")
        subprocess.run([sys.executable, __file__, "--commit-child", str(tmp / "commits.h5"),
                        "--checkpoints", str(args.checkpoints)], check=True)
    if args.commits_only:
        return
    ltcs = {"this": LTC}
    if args.baseline:
        ltcs = {"baseline": shlex.split(args.baseline), **ltcs}
    runs = [
        ("export 100k objects, json", [str(objects_map), "--format", "json", "-o", str(tmp / "out.json")], "export"),
        ("export 100k objects, geojson WGS84",
         [str(objects_map), "--format", "geojson", "--origin", "36.72,-4.42,20", "-o", str(tmp / "out.geojson")],
         "export"),
        (f"query --id 5, {args.events:,} events", [str(events_map), "--id", "5"], "query"),
        (f"info, {args.events:,} events", [str(events_map)], "info"),
        (f"query --removed, {args.events:,} events", [str(events_map), "--removed"], "query"),
        ("render 4 frames of sample_data/lap1, 100k objects",
         [str(objects_map), "-o", str(tmp / "frames.png"), "--recording", str(ROOT / "sample_data" / "lap1"),
          "--scale", "0.5"], "render"),
    ]
    print("CPU s (user + system), wall s, max RSS MiB of each command")
    for label, rest, command in runs:
        for name, ltc in ltcs.items():
            cpu, wall, rss = measure([*ltc, command, *rest])
            print(f"{label:<40} {name:<9} {cpu:6.2f} s CPU {wall:6.2f} s wall {rss:7.0f} MiB")


if __name__ == "__main__":
    main()

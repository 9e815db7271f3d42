"""bench_real.py's passes with the camera stopped (issue 9, fifty-fourth round): tum-fr1-rpy with the
camera standing for 150 frames after frames 40, 120 and 200, still or with a localiser's noise,
mapped with the default ``frames.still_move`` / ``still_turn`` and with every frame mapped."""

from __future__ import annotations

from pathlib import Path

from ltc_cli.config import load_config
from ltc_cli.ingest.session import ingest
from ltc_cli.map.store import load_map
from real_census import census
from tests.real_truth import check
from tests.replay import Stopped

STOPS, STOP_FRAMES, JITTER = (40, 120, 200), 150, (0.005, 0.2)
READERS = {"stopped": Stopped(STOPS, STOP_FRAMES), "stopped-jitter": Stopped(STOPS, STOP_FRAMES, JITTER, seed=1)}
LABELS = {"stopped": "standing still", "stopped-jitter": f"with a localiser's noise of {1000 * JITTER[0]:.0f} mm "
          f"and {JITTER[1]} degrees"}


def stopped_lines(name: str, path: Path, tmp: Path, sets: list, verdict) -> list[str]:
    """One line per way of standing: objects and the hand-measured places held, with the default
    settings and with every frame mapped (``frames.still_move: null``, the paper)."""
    out = [f"  the camera stopped for {STOP_FRAMES} frames after frames {', '.join(map(str, STOPS))} (a robot "
           "waiting):"]
    for reader, label in LABELS.items():
        parts = []
        for how, extra in (("", []), ("every frame mapped", ["frames.still_move=null"])):
            m = tmp / f"{name}-{reader}-{len(extra)}.h5"
            s = ingest([path], m, load_config(None, [*sets, *extra]), reader=reader)
            counts, _ = census(m)
            held = check(load_map(m))
            missed = [lm.name for lm, ok, _ in held if not ok]
            still = f", {s.frames_still} of {s.frames_still + s.frames_done} frames still" if s.frames_still else ""
            parts.append(f"{how + ': ' if how else ''}{sum(counts.values())} objects ({verdict(name, counts)}), "
                         f"{len(held) - len(missed)} of {len(held)} places{still}"
                         + (f" (not: {'; '.join(missed)})" if missed else ""))
        out.append(f"    {label}: {parts[0]}; {parts[1]}")
    return out

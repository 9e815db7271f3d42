"""Every figure of issue 11 in one run: bench_speed.py (whole ingest vs decoding, start-up,
detectors per model and provider, end-to-end frames/s with ``--jobs 1`` and ``--jobs 2``, where a
real-detector frame's CPU goes, a ``--jobs 2`` run in time) and then bench_scale.py (checkpoints on
maps of 15k, 150k and 1.5M events, the 100k-object exports with their peak memory, the commands
on a 1.5M-event map). Each runs as its own child, one after the other, so that neither's memory
or threads weigh on the other's figures.

    python benchmarks/bench_issue11.py [--baseline CMD] [--openvino-python CMD] [--keep DIR]

``--baseline`` and ``--openvino-python`` go to both scripts / bench_speed.py as they document;
``--keep`` is bench_scale.py's folder for its built maps (reused when given twice).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--baseline", help="another ltc command line, measured beside this one")
    ap.add_argument("--openvino-python", metavar="CMD", help="a Python with onnxruntime-openvino (bench_speed.py)")
    ap.add_argument("--keep", type=Path, help="bench_scale.py's folder for its maps")
    args = ap.parse_args()
    common = ["--baseline", args.baseline] if args.baseline else []
    speed = [*common] + (["--openvino-python", args.openvino_python] if args.openvino_python else [])
    scale = [*common] + (["--keep", str(args.keep)] if args.keep else [])
    for script, extra in (("bench_speed.py", speed), ("bench_scale.py", scale)):
        print(f"== {script}", flush=True)
        code = subprocess.run([sys.executable, str(HERE / script), *extra]).returncode
        if code:
            return code
    return 0


if __name__ == "__main__":
    sys.exit(main())

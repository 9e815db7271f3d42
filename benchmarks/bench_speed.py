"""Speed of everything around the four stages (issue 11), in one run:

1. a whole ``ltc ingest`` of a simulated 640x480 lap (recorded detector; the process's CPU time,
   start-up included) per frame, vs a loop that only decodes the lap's depth and colour images
   (OpenCV, and Pillow as ltc decoded before) per frame: the ratio;
2. start-up CPU of ``ltc --help`` and ``ltc info MAP`` (median of ``--repeat`` runs);
3. detector ms per frame (wall and CPU, one intra-op thread) of the shared YOLOv8n-seg int8 and
   fp32 models on real TUM frames, for each execution provider available: cpu, and openvino (f32,
   and the fp32 model with the bf16 precision hint) when this Python has onnxruntime-openvino or
   ``--openvino-python`` names one that has;
4. end-to-end ``ltc ingest`` of the 232 real tum-fr1-rpy frames with the fp32 model, ``--jobs 1``
   and ``--jobs 2``: frames/s (wall) and CPU ms per frame; with openvino too when available
   (``--jobs 2``, f32 and bf16). The load average is printed before and after;
5. where the CPU of that ingest goes, per frame (``--jobs 1``, one intra-op thread): the fixed
   cost (the same command again on the finished map: start-up, detector session, frame set-up,
   map load), loading (depth, colour header, pose; then colour decoding), the detector's
   letterbox, inference and post-processing (a probe timing each part), and the rest: mapping,
   i.e. the four stages, checkpoints and the session's own loop;
6. the same ``--jobs 2`` ingest in time (in-process, the library's ingest): start-up until the
   first frame is mapped, then the steady rate (frames/s, CPU per frame, cores busy); with
   openvino bf16 too when available. The steady rate is what ``--jobs`` overlaps; the start-up
   (~1.5 s wall) is paid once.

``--baseline CMD`` runs items 1, 2 and 4 with another ltc too (e.g. a checkout of an older commit:
``--baseline "env PYTHONPATH=/tmp/old python -c 'from ltc_cli.cli import main; main()'"``), in the
same run, so that before and after meet the same machine load. CPU times are user + system of the
child process (resource.getrusage), so other engineers' work on a shared machine changes the wall
times more than these.

    python benchmarks/bench_speed.py [--sim DIR] [--frames 30] [--repeat 7] [--baseline CMD]
                                     [--openvino-python PATH] [--items 1,2,3,4,5,6] [--runs 1]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shlex
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
# ../shared beside the checkout (a worktree under wt/ has it two levels up)
SHARED = next((p for p in (ROOT.parent / "shared", ROOT.parent.parent / "shared") if p.is_dir()), ROOT.parent / "shared")
MODELS = {"int8": SHARED / "models" / "yolov8n-seg_int8.onnx", "fp32": SHARED / "models" / "yolov8n-seg_fp32.onnx"}
TUM = SHARED / "data" / "tum-fr1-rpy"
LTC = [sys.executable, "-c", "import sys; sys.argv[0] = 'ltc'; from ltc_cli.cli import main; main()"]


def child_env() -> dict:
    """The children's environment: this checkout first on PYTHONPATH. They run in the temporary
    folder, not here: ``python -c`` puts its working folder before PYTHONPATH, so a ``--baseline``
    of ``env PYTHONPATH=/old python -c ...`` started here imported this checkout, not /old (until
    the forty-fifth round, when "baseline" and "now" measured the same code)."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    return env


def run_cpu(cmd: list[str], env: dict | None = None) -> tuple[float, float, str]:
    """(CPU s, wall s, stdout) of one child process; raises if it fails."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True, env=child_env() if env is None else env,
                          cwd=tempfile.gettempdir())
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise SystemExit(f"{shlex.join(cmd)} failed:\n{done.stderr}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return cpu, wall, done.stdout


# -- 1. whole ingest vs decoding ------------------------------------------------------------------

def decode_only(lap: Path) -> dict:
    """CPU ms per frame of decoding every depth and colour image of the lap (no ltc code)."""
    import cv2
    import numpy as np
    from PIL import Image

    def cpu() -> float:
        r = resource.getrusage(resource.RUSAGE_SELF)
        return r.ru_utime + r.ru_stime

    depth = sorted((lap / "depth").iterdir())
    rgb = sorted((lap / "rgb").iterdir())
    out = {}
    for name, read_depth, read_rgb in [
        ("opencv", lambda p: cv2.imread(str(p), cv2.IMREAD_UNCHANGED), lambda p: cv2.imread(str(p), cv2.IMREAD_UNCHANGED)),
        ("pillow", lambda p: np.asarray(Image.open(p)), lambda p: np.asarray(Image.open(p).convert("RGB"))),
    ]:
        c0 = cpu()
        for p in depth:
            read_depth(p)
        c1 = cpu()
        for p in rgb:
            read_rgb(p)
        c2 = cpu()
        out[name] = {"depth": (c1 - c0) / len(depth) * 1e3, "both": (c2 - c0) / len(depth) * 1e3}
    return out


def whole_ingest(ltc: list[str], lap: Path, tmp: Path, tag: str) -> float:
    m = tmp / f"sim-{tag}.h5"
    m.unlink(missing_ok=True)
    cpu, _, _ = run_cpu([*ltc, "ingest", str(lap), "--map", str(m)])
    return cpu / len(list((lap / "depth").iterdir())) * 1e3


# -- 2. start-up ----------------------------------------------------------------------------------

def startup(ltc: list[str], args: list[str], repeat: int) -> float:
    return statistics.median(run_cpu([*ltc, *args])[0] for _ in range(repeat))


# -- 3. detector alone ----------------------------------------------------------------------------

DETECTOR_PROBE = """
import json, resource, sys, time
from ltc_cli.recordings.open import open_recording
from ltc_cli.errors import LtcError
from ltc_cli.threads import mapping_threads
from ltc_plugins.onnx.yolo_seg import YoloSegDetector
model, provider, precision, tum, n = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4], int(sys.argv[5])
limits = mapping_threads(1)
limits.__enter__()  # one BLAS thread, as in an ingest (kept referenced: dropping it would exit)
try:
    det = YoloSegDetector.from_options(None, {"model": model, "provider": provider, "threads": 1,
                                              **({"precision": precision} if precision != "f32" else {})})
except LtcError as exc:
    print(json.dumps({"error": str(exc).splitlines()[0]}))
    raise SystemExit(0)
rec = open_recording(tum)
frames = [ref.load() for ref in rec.frames[: n + 3]]
for f in frames:
    f.rgb
def cpu():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime
for f in frames[:3]:
    det.detect(f)  # warm-up (OpenVINO compiles the model on the first run)
c0, t0 = cpu(), time.perf_counter()
for f in frames[3:]:
    det.detect(f)
print(json.dumps({"wall": (time.perf_counter() - t0) / n * 1e3, "cpu": (cpu() - c0) / n * 1e3}))
"""


def detector_ms(python: list[str], model: Path, provider: str, n: int, precision: str = "f32") -> dict:
    _, _, out = run_cpu([*python, "-c", DETECTOR_PROBE, str(model), provider, precision, str(TUM), str(n)])
    return json.loads(out.strip().splitlines()[-1])


def has_openvino(python: list[str]) -> bool:
    probe = "import ltc_cli, onnxruntime as o; print('OpenVINOExecutionProvider' in o.get_available_providers())"
    done = subprocess.run([*python, "-c", probe], capture_output=True, text=True, env=child_env(), cwd=tempfile.gettempdir())
    return done.returncode == 0 and done.stdout.strip() == "True"


# -- 5. the CPU budget of a real-detector ingest --------------------------------------------------

BUDGET_PROBE = """
import json, resource, sys
from ltc_cli.recordings.open import open_recording
from ltc_cli.threads import mapping_threads
from ltc_plugins.onnx.yolo_seg import YoloSegDetector
limits = mapping_threads(1)
limits.__enter__()
det = YoloSegDetector.from_options(None, {"model": sys.argv[1], "threads": 1})
refs = open_recording(sys.argv[2]).frames
def cpu():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime
part = dict(load=0.0, colour=0.0, letterbox=0.0, inference=0.0)
letterbox, session = det.letterbox, det.session
class Timed:  # the session, its run timed
    def __getattr__(self, name):
        return getattr(session, name)
    def run(self, *a):
        c = cpu(); out = session.run(*a); part["inference"] += cpu() - c; return out
def timed_letterbox(rgb):
    c = cpu(); out = letterbox(rgb); part["letterbox"] += cpu() - c; return out
det.session, det.letterbox = Timed(), timed_letterbox
det.detect(refs[0].load())  # warm-up
part = dict.fromkeys(part, 0.0)
total = 0.0
for ref in refs:
    c0 = cpu(); frame = ref.load(); c1 = cpu(); frame.rgb; c2 = cpu(); det.detect(frame); c3 = cpu()
    part["load"] += c1 - c0; part["colour"] += c2 - c1; total += c3 - c2
part["post-processing"] = total - part["letterbox"] - part["inference"]
print(json.dumps({k: v / len(refs) * 1e3 for k, v in part.items()}))
"""


def item_budget(tmp: Path) -> None:
    m = tmp / "tum-budget.h5"
    m.unlink(missing_ok=True)
    cmd = [*LTC, "ingest", str(TUM), "--map", str(m), "--detector", "onnx-yolo-seg", "--set",
           f"detector.options.model={MODELS['fp32']}", "--set", "detector.options.threads=1", "--jobs", "1"]
    whole, _, out = run_cpu(cmd)
    n = int(out.split(":")[1].split("frames ingested")[0])
    fixed, _, _ = run_cpu(cmd)  # every frame is in the map now: what does not depend on the frames
    _, _, out = run_cpu([sys.executable, "-c", BUDGET_PROBE, str(MODELS["fp32"]), str(TUM)])
    parts = json.loads(out.strip().splitlines()[-1])
    per_frame = whole / n * 1e3
    rows = {"fixed (start-up, session, set-up, map)": fixed / n * 1e3, **parts}
    rows["mapping (the rest)"] = per_frame - sum(rows.values())
    print(f"5. CPU ms per frame of the fp32 ingest, --jobs 1, 1 intra-op thread ({n} frames): {per_frame:.1f}")
    for name, ms in rows.items():
        print(f"   {name:<40}: {ms:5.1f}")


# -- 6. start-up and steady rate -----------------------------------------------------------------

TIMELINE_PROBE = """
import json, os, resource, sys, time
t_start = time.perf_counter()
from ltc_cli.config import load_config
from ltc_cli.threads import mapping_threads
out, model, tum, sets = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4:]
def cpu():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime
marks = []
with mapping_threads(2):
    from ltc_cli.ingest.session import ingest
    cfg = load_config(None, ["detector.name=onnx-yolo-seg", f"detector.options.model={model}", *sets])
    ingest([tum], out, cfg, jobs=2, on_frame=lambda s: marks.append((time.perf_counter(), cpu())))
t_end = time.perf_counter()
(t1, c1), (tn, cn) = marks[0], marks[-1]
n = len(marks)
print(json.dumps({"first": t1 - t_start, "fps": (n - 1) / (tn - t1), "ms": (cn - c1) / (n - 1) * 1e3,
                  "cores": (cn - c1) / (tn - t1), "whole": n / (t_end - t_start)}))
"""


def item_timeline(ov: list[str] | None, tmp: Path) -> None:
    print(f"6. --jobs 2 in time (load average {os.getloadavg()[0]:.2f}): start-up to the first frame mapped; "
          "then frames/s, CPU ms per frame, cores busy")
    runs = [("cpu f32", [sys.executable], [])]
    if ov is not None:
        runs.append(("openvino bf16", ov, ["detector.options.provider=openvino", "detector.options.precision=bf16"]))
    for tag, python, sets in runs:
        m = tmp / "tum-timeline.h5"
        m.unlink(missing_ok=True)
        _, _, out = run_cpu([*python, "-c", TIMELINE_PROBE, str(m), str(MODELS["fp32"]), str(TUM), *sets])
        r = json.loads(out.strip().splitlines()[-1])
        print(f"   {tag:<13}: start-up {r['first']:.2f} s; steady {r['fps']:5.1f} frames/s, {r['ms']:5.1f} ms, "
              f"{r['cores']:.2f} cores; whole run {r['whole']:5.1f} frames/s")


# -- 4. end to end --------------------------------------------------------------------------------

def end_to_end(ltc: list[str], jobs: int, tmp: Path, tag: str, options: tuple = ()) -> tuple[float, float]:
    m = tmp / f"tum-{tag}-j{jobs}.h5"
    m.unlink(missing_ok=True)
    sets = [a for o in options for a in ("--set", f"detector.options.{o}")]
    cpu, wall, out = run_cpu([*ltc, "ingest", str(TUM), "--map", str(m), "--detector", "onnx-yolo-seg",
                              "--set", f"detector.options.model={MODELS['fp32']}", *sets, "--jobs", str(jobs)])
    n = int(out.split(":")[1].split("frames ingested")[0])
    return n / wall, cpu / n * 1e3


def item_decode_and_startup(args, ltcs: dict, tmp: Path, items: set) -> None:
    lap = args.sim
    if lap is None:
        run_cpu([*LTC, "simulate", str(tmp / "sim"), "--scene", "small", "--laps", "1", "--seed", "0"])
        lap = tmp / "sim" / "lap1"
    if 1 in items:
        n_lap = len(list((lap / "depth").iterdir()))
        print(f"1. simulated 640x480 lap ({n_lap} frames, recorded detector): CPU ms per frame")
        dec = decode_only(lap)
        for name in ("opencv", "pillow"):
            print(f"   decode only, {name:<7}: depth {dec[name]['depth']:6.2f}, depth + colour {dec[name]['both']:6.2f}")
    for tag, ltc in ltcs.items():
        ms = whole_ingest(ltc, lap, tmp, tag)
        if 1 in items:
            print(f"   whole ingest, {tag:<8}: {ms:6.2f}  = {ms / dec['opencv']['both']:.2f}x decode (OpenCV, depth + colour), "
                  f"{ms / dec['pillow']['both']:.2f}x (Pillow)")
    if 2 in items:
        print(f"2. start-up, median CPU s of {args.repeat} runs")
        info_map = tmp / "sim-now.h5"
        for tag, ltc in ltcs.items():
            print(f"   {tag:<8}: ltc --help {startup(ltc, ['--help'], args.repeat):.3f}, "
                  f"ltc info {startup(ltc, ['info', str(info_map)], args.repeat):.3f}")


def openvino_python(args) -> list[str] | None:
    ov = shlex.split(args.openvino_python) if args.openvino_python else [sys.executable]
    return ov if has_openvino(ov) else None


def item_detector(args, ov: list[str] | None) -> None:
    print(f"3. detector alone, ms per frame on {args.frames} TUM frames (1 intra-op thread): wall / CPU")
    runs = [("cpu", "f32", [sys.executable], name, model) for name, model in MODELS.items()]
    if ov is None:
        print("   openvino: not available (no onnxruntime-openvino in this Python; see --openvino-python)")
    else:
        runs += [("openvino", "f32", ov, name, model) for name, model in MODELS.items()]
        runs += [("openvino", "bf16", ov, "fp32", MODELS["fp32"])]
    for provider, precision, python, name, model in runs:
        r = detector_ms(python, model, provider, args.frames, precision)
        label = f"{name:<4} {provider:<8} {precision:<4}"
        if "error" in r:
            print(f"   {label}: fails: {r['error'][-150:]}")
            continue
        print(f"   {label}: {r['wall']:6.1f} / {r['cpu']:6.1f}")


def item_end_to_end(args, ltcs: dict, ov: list[str] | None, tmp: Path) -> None:
    n_tum = len(list((TUM / "rgb").iterdir()))
    print(f"4. end to end, tum-fr1-rpy ({n_tum} frames), fp32 model: frames/s (wall), CPU ms per frame; "
          f"load average {os.getloadavg()[0]:.2f}")
    runs = [(tag, ltc, jobs, ()) for tag, ltc in ltcs.items() for jobs in (1, 2)]
    if ov is not None:
        ov_ltc = [*ov, *LTC[1:]]
        runs += [(f"openvino {p}", ov_ltc, 2, ("provider=openvino", f"precision={p}")) for p in ("f32", "bf16")]
    best: dict = {}
    # Rounds of one run of each kind, so that a change of load on a shared machine hits every kind;
    # the best of the rounds (highest frames/s, lowest CPU) is the least disturbed figure.
    for _ in range(args.runs):
        for tag, ltc, jobs, options in runs:
            fps, ms = end_to_end(ltc, jobs, tmp, tag.replace(" ", "-"), options)
            print(f"   {tag:<13} --jobs {jobs}: {fps:5.1f} frames/s, {ms:5.1f} ms CPU per frame", flush=True)
            f0, m0 = best.get((tag, jobs), (0.0, float("inf")))
            best[(tag, jobs)] = (max(f0, fps), min(m0, ms))
    if args.runs > 1:
        print(f"   best of {args.runs}:")
        for (tag, jobs), (fps, ms) in best.items():
            print(f"   {tag:<13} --jobs {jobs}: {fps:5.1f} frames/s, {ms:5.1f} ms CPU per frame")
    print(f"   load average after: {os.getloadavg()[0]:.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sim", type=Path, help="a simulated lap folder to reuse (default: simulate one, ~20 s)")
    ap.add_argument("--frames", type=int, default=30, help="TUM frames timed per detector figure")
    ap.add_argument("--repeat", type=int, default=7, help="start-up runs (median)")
    ap.add_argument("--baseline", help="another ltc command line to measure items 1, 2 and 4 with")
    ap.add_argument("--openvino-python", metavar="CMD",
                    help="a Python command line with onnxruntime-openvino that imports ltc_cli and ltc_plugins, "
                         "e.g. \"env PYTHONPATH=/tmp/ltc-tree /tmp/ov-venv/bin/python\"")
    ap.add_argument("--items", default="1,2,3,4,5,6", help="which figures to measure (default all)")
    ap.add_argument("--runs", type=int, default=1, help="rounds of end-to-end runs (item 4); the best is printed")
    args = ap.parse_args()
    items = {int(i) for i in args.items.split(",")}
    ltcs = {"now": LTC}
    if args.baseline:
        ltcs = {"baseline": shlex.split(args.baseline), **ltcs}
    ov = openvino_python(args) if items & {3, 4, 6} else None
    with tempfile.TemporaryDirectory(prefix="bench-speed-") as tmp_name:
        tmp = Path(tmp_name)
        if items & {1, 2}:
            item_decode_and_startup(args, ltcs, tmp, items)
        if 3 in items:
            item_detector(args, ov)
        if 4 in items:
            item_end_to_end(args, ltcs, ov, tmp)
        if 5 in items:
            item_budget(tmp)
        if 6 in items:
            item_timeline(ov, tmp)


if __name__ == "__main__":
    main()

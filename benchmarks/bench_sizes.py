"""tum-fr1-rpy drawn at other image sizes, or with a noisier depth sensor's error, mapped with
pixel settings scaled with the image (``modeling.scale_pixels``, the default) and as given (the
paper's): objects per class, the chairs' boxes, and the hand-measured places of
tests/real_truth.py held, over the whole recording and its even and odd frames (docs/decisions.md,
issue 9 forty-ninth round).

Each colour image is resized (area or bilinear), each depth image by nearest neighbour, into a
temporary TUM folder, and the README's fr1 intrinsics are scaled with them. ``--depth-noise K``
adds a stereo camera's error to every reading: a smooth random field (correlated over about 4 px
of a 640 x 480 image, a new draw per frame) of standard deviation K * Z^2 metres (a RealSense D435
is about 0.01: 1 cm at 1 m, 4 cm at 2 m). ltc measures the error on the frames by default
(``modeling.depth_noise: auto``; each variant prints what it measured); ``--tell-noise`` sets
``modeling.depth_noise`` to the K added instead, and ``--set modeling.depth_noise=0.0019`` to a
Kinect's, which is what ltc allowed for before it measured. The shared fp32 model detects each frame once per
variant (tests/replay.py Replay); both settings map its detections (at 640 x 480 and smaller they
are the same, so one is mapped). Needs ../shared; prints what it measured.

    python benchmarks/bench_sizes.py [--sizes 0.5,1.5,2] [--depth-noise 0,0.01 [--tell-noise]]
                                     [--set key=value]... [--model ../shared/models/yolov8n-seg_fp32.onnx]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import zlib
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from bench_real import SHARED, census, verdict  # noqa: E402
from ltc_cli import hookimpl, plugins  # noqa: E402
from ltc_cli.config import load_config  # noqa: E402
from ltc_cli.ingest.session import ingest  # noqa: E402
from ltc_cli.map.model import ACTIVE, top_class  # noqa: E402
from ltc_cli.map.store import load_map  # noqa: E402
from tests.real_truth import TUM_FR1_RPY, check  # noqa: E402
from tests.replay import Replay  # noqa: E402

NAME = "tum-fr1-rpy"
FR1 = (517.3, 516.5, 318.6, 255.3)  # the recording's README
PASSES = ("all frames", "even frames", "odd frames")


class SizesPlugin:
    @hookimpl
    def register_detectors(self, register):
        register("replay-yolo", Replay)


def stereo_noise(depth_raw: np.ndarray, k: float, seed: int, scale: float) -> np.ndarray:
    """A 16-bit TUM depth image (metres * 5000) with a smooth error of std k * Z^2 metres added
    where it has a reading (see the module's docstring)."""
    z = depth_raw.astype(np.float64) / 5000.0
    field = cv2.GaussianBlur(np.random.default_rng(seed).standard_normal(z.shape), (0, 0), 4.0 * scale)
    noisy = z + field / field.std() * k * z * z
    return np.where(depth_raw > 0, np.clip(np.round(noisy * 5000.0), 1, 65535), 0).astype(np.uint16)


def draw_at(src: Path, scale: float, out: Path, noise: float = 0.0) -> list[float]:
    """The recording at ``scale`` times its size in ``out`` (TUM layout), its depth with
    :func:`stereo_noise` ``noise``, with its even and odd frames beside it (``out``-even,
    ``out``-odd: rgb.txt filtered, the images linked); returns the scaled intrinsics [fx, fy, cx,
    cy] (pixel centres kept: c' = (c + 0.5) * scale - 0.5)."""
    for sub in ("rgb", "depth"):
        (out / sub).mkdir(parents=True, exist_ok=True)
        for f in sorted((src / sub).iterdir()):
            im = cv2.imread(str(f), cv2.IMREAD_UNCHANGED)
            size = (int(round(im.shape[1] * scale)), int(round(im.shape[0] * scale)))
            how = cv2.INTER_NEAREST if sub == "depth" else cv2.INTER_AREA if scale < 1 else cv2.INTER_LINEAR
            im = cv2.resize(im, size, interpolation=how)
            if sub == "depth" and noise > 0:
                im = stereo_noise(im, noise, zlib.crc32(f.name.encode()), scale)
            cv2.imwrite(str(out / sub / f.name), im, [cv2.IMWRITE_JPEG_QUALITY, 92] if f.suffix == ".jpg" else [])
    for name in ("rgb.txt", "depth.txt", "groundtruth.txt"):
        (out / name).write_text((src / name).read_text())
    lines = (src / "rgb.txt").read_text().splitlines()
    data = [ln for ln in lines if ln.strip() and not ln.startswith("#")]
    for part, start in (("even", 0), ("odd", 1)):
        d = out.parent / f"{out.name}-{part}"
        d.mkdir()
        for sub in ("rgb", "depth"):
            (d / sub).symlink_to(out / sub)
        for name in ("depth.txt", "groundtruth.txt"):
            (d / name).write_text((src / name).read_text())
        (d / "rgb.txt").write_text("\n".join(data[start::2]) + "\n")
    fx, fy, cx, cy = FR1
    return [fx * scale, fy * scale, (cx + 0.5) * scale - 0.5, (cy + 0.5) * scale - 0.5]


def chairs(map_path) -> str:
    smap = load_map(map_path)
    t = smap.objects
    rows = [r for r in np.flatnonzero(t.status == ACTIVE) if smap.classes[int(top_class(t.scores[r]))] == "chair"]
    return ", ".join(f"{max(t.size[r][:2]):.2f} x {min(t.size[r][:2]):.2f} m" for r in rows) or "none"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="0.5,1.5,2", help="scales of the images, comma-separated")
    ap.add_argument("--depth-noise", default="0", help="K of a stereo error of std K * Z^2 m, comma-separated")
    ap.add_argument("--tell-noise", action="store_true",
                    help="also tell ltc the added error (modeling.depth_noise = K), as a user of that sensor would")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="a setting for every pass")
    ap.add_argument("--model", default=str(SHARED / "models" / "yolov8n-seg_fp32.onnx"))
    args = ap.parse_args()
    src = SHARED / "data" / NAME
    if not src.is_dir() or not Path(args.model).is_file():
        sys.exit(f"needs {src} and {args.model}")
    plugins.register_plugin(SizesPlugin(), name="bench-sizes")
    settings = {"scaled (default)": [], "as given": ["modeling.scale_pixels=false"]}
    with tempfile.TemporaryDirectory() as tmp:
        variants = [(float(a), float(b)) for a in args.sizes.split(",") for b in args.depth_noise.split(",")]
        for scale, noise in variants:
            folder = Path(tmp) / f"x{scale:g}-n{noise:g}"
            intr = draw_at(src, scale, folder, noise)
            Replay.store.clear()  # a recording's identity is its lists, the same at every size
            w, h = int(round(640 * scale)), int(round(480 * scale))
            print(f"{NAME} at {w} x {h}" + (f", depth error {noise:g} * Z^2 m" if noise else "")
                  + (" (told: modeling.depth_noise)" if noise and args.tell_noise else "")
                  + f" (intrinsics {', '.join(f'{v:.2f}' for v in intr)}):")
            for label, sets in list(settings.items())[: 2 if scale > 1 else 1]:
                told = [f"modeling.depth_noise={noise:g}"] if args.tell_noise and noise > 0 else []
                cfg = load_config(None, ["detector.name=replay-yolo", f"detector.options.model={args.model}", *sets,
                                         *args.set, *told])
                held, lines = 0, []
                for part, path in zip(PASSES, (folder, folder.parent / f"{folder.name}-even",
                                               folder.parent / f"{folder.name}-odd")):
                    m = Path(tmp) / f"{folder.name}-{part[:3]}-{label[:6]}.h5"
                    ingest([path], m, cfg, reader="tum", reader_options={"intrinsics": intr})
                    counts, _ = census(m)
                    smap = load_map(m)
                    res = check(smap, TUM_FR1_RPY)
                    measured = [c.get("depth_noise") for c in json.loads(smap.sessions[-1]["cameras"])]
                    held += sum(ok for _, ok, _ in res)
                    wrong = "; ".join(f"{lm.name}: {where}" for lm, ok, where in res if not ok)
                    lines.append(f"    {part}: {sum(counts.values())} objects ({verdict(NAME, counts)}); chairs "
                                 f"{chairs(m)}; places {sum(ok for _, ok, _ in res)} of {len(res)}; depth "
                                 f"noise measured {', '.join('none' if k is None else f'{k:.4f}' for k in measured)}"
                                 + (f" ({wrong})" if wrong else ""))
                print(f"  pixel settings {label}: places held {held} of {len(PASSES) * len(TUM_FR1_RPY)}")
                print("\n".join(lines))


if __name__ == "__main__":
    main()

"""The ``ltc`` command line: a thin layer that parses options, calls the library and prints.

Library errors (``LtcError``) become one line on stderr and exit status 1 (2 for usage errors, as
click does); ``--debug`` shows the traceback instead.
"""

from __future__ import annotations

import json
import math
import os
import signal
import sys
from collections import Counter
from contextlib import contextmanager
from typing import Callable

import click

from ltc_cli import __version__, plugins
from ltc_cli.config import load_config
from ltc_cli.errors import LtcError
from ltc_cli.ingest.signals import stop_on_signals
from ltc_cli.text import plural, skipped_breakdown
from ltc_cli.threads import mapping_threads


class LtcGroup(click.Group):
    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except LtcError as exc:
            if ctx.params.get("debug"):
                raise
            raise click.ClickException(str(exc)) from None
        except KeyboardInterrupt:
            click.echo("interrupted", err=True)
            ctx.exit(130)


@click.group(cls=LtcGroup)
@click.version_option(__version__, prog_name="ltc")
@click.option("--debug", is_flag=True, help="Show tracebacks instead of one-line errors.")
def cli(debug):
    """ltc: object-oriented semantic maps that stay true over months (LTC-Mapping)."""


_plural = plural


def warn_line(message: str) -> None:
    click.echo(f"warning: {message}", err=True)


@contextmanager
def progress_bar(label: str, count: Callable[[], int]):
    """A progress bar on a terminal, of ``count()`` steps; nothing in a pipe. Yields the callback
    a long-running library call takes as ``progress`` (None in a pipe)."""
    if not sys.stderr.isatty():
        yield None
        return
    with click.progressbar(length=count(), label=label, file=sys.stderr) as bar:
        yield bar.update


READER_OPTION_HELP = ("A reader option, value read as YAML (repeat for several), e.g. -r intrinsics=518,519,325.5,253.5 "
                       "for a plain folder, or -r color_topic=/camera/color/image_raw for a bag.")


def reader_options(items) -> dict:
    """-r KEY=VALUE items -> the reader's options mapping (dotted keys nest, values are YAML)."""
    from ltc_cli.config import parse_set

    out: dict = {}
    for item in items:
        if "=" not in item.strip("="):
            raise click.BadParameter(f"expected KEY=VALUE, not {item!r}", param_hint="--reader-option")
        key, value = next(iter(parse_set(item).items()))
        if isinstance(value, dict) and isinstance(out.get(key), dict):  # -r a.b=1 -r a.c=2: both
            out[key] = {**out[key], **value}
        else:
            out[key] = value
    return out
def dask_options(command):
    command = click.option("--dask-batch", default=4, show_default=True, type=click.IntRange(1, 1000),
                           help="Frames per Dask task (fewer, larger tasks cost the scheduler less).")(command)
    return click.option(
        "--dask", "dask_spec", metavar="local|ADDRESS",
        help="Load, detect and model frames on Dask workers (extra ltc[dask]): 'local' (or local:N workers) on "
             "this machine, or a scheduler's address; this process maps them in order (docs/fleet.md).")(command)


@cli.command()
@click.argument("recordings", nargs=-1, required=True, type=click.Path())
@click.option("--map", "map_path", required=True, type=click.Path(dir_okay=False), help="The map file (.h5); created if absent.")
@click.option("--detector", help="Detector plugin (default: recorded).")
@click.option("--metric", help="Association metric plugin (default: vertex).")
@click.option("--policy", help="Maintenance policy plugin (default: non-detection).")
@click.option("--config", "config_file", type=click.Path(dir_okay=False), help="YAML file of settings.")
@click.option("--set", "sets", multiple=True, metavar="KEY=VALUE", help="Override one setting, e.g. --set association.threshold_same_class=0.5")
@click.option("--calibration", type=click.Path(dir_okay=False), help="Calibration file from `ltc calibrate` (sets v_Other).")
@click.option("--checkpoint-every", default=50, show_default=True, type=click.IntRange(min=0), help="Commit the map every N frames (0: only at the end).")
@click.option("--strict", is_flag=True, help="Stop at the first bad frame instead of skipping it.")
@click.option("--format", "reader", help="Recording reader (default: detected from the folder).")
@click.option("--reader-option", "-r", "reader_opts", multiple=True, metavar="KEY=VALUE", help=READER_OPTION_HELP)
@click.option("--jobs", "-j", default=1, show_default=True, type=click.IntRange(1, 64),
              help="Threads that load and detect the next frames while the current one is mapped (the map is the same as with 1).")
@click.option("--revisit", is_flag=True,
              help="Map recordings already in the map again, as a new session (the same route driven again); "
                   "an interrupted revisit resumes with the same command.")
@click.option("--frames", "frame_spec", metavar="START:STOP[:STEP]",
              help="Map only this range of each recording's frames (0 is the first; e.g. 0:1000, 1000: or ::2), "
                   "as its own session: a recording that loops its route, one loop per session.")
@dask_options
def ingest(recordings, map_path, detector, metric, policy, config_file, sets, calibration, checkpoint_every, strict,
           reader, reader_opts, jobs, revisit, frame_spec, dask_spec, dask_batch):
    """Ingest RECORDING folders into the map MAP.h5 (resumes where an interrupted run stopped)."""
    # The handlers go in before anything slow (imports, reading settings, opening recordings), so
    # that a SIGTERM is never met by the default handler, which would end the process uncommitted.
    if dask_spec and jobs > 1:
        raise click.UsageError("--jobs and --dask: give one (with --dask the workers run ahead)")
    with stop_on_signals() as stop, mapping_threads(jobs):
        from ltc_cli.ingest.cluster import cluster_for
        from ltc_cli.ingest.session import ingest as run_ingest
        from ltc_cli.ingest.session_row import sessions_of
        from ltc_cli.recordings.open import count_frames, frame_range
        from ltc_cli.tools.calibration_file import load_calibration

        frames = frame_range(frame_spec) if frame_spec is not None else None
        cfg = load_config(config_file, sets)
        if detector:
            cfg["detector"]["name"] = detector
        if metric:
            cfg["association"]["metric"] = metric
        if policy:
            cfg["maintenance"]["policy"] = policy
        calib = load_calibration(calibration) if calibration else None
        r_opts = reader_options(reader_opts)
        with cluster_for(dask_spec, dask_batch) as cluster, \
                progress_bar("ingest", lambda: count_frames(recordings, reader, r_opts, sessions_of(map_path),
                                                            frames)) as progress:
            summary = run_ingest(
                list(recordings), map_path, cfg, reader=reader, reader_options=r_opts, calibration=calib,
                checkpoint_every=checkpoint_every, strict=strict, progress=progress, warn=warn_line,
                should_stop=lambda: stop["signal"] is not None, jobs=jobs, revisit=revisit, cluster=cluster,
                frames=frames,
            )
    visit = f"visit {summary.visit}; " if summary.visit > 1 else ""
    why = f" ({skipped_breakdown(summary.skipped_reasons)})" if summary.skipped_reasons else ""
    line = (
        f"{map_path}: {_plural(summary.frames_done, 'frame')} ingested, {summary.frames_skipped} skipped{why}, "
        f"{f'{summary.frames_still} still (the camera had not moved), ' if summary.frames_still else ''}"
        f"{summary.frames_already} already in the map; objects {summary.created} created, "
        f"{summary.merged} merged, {summary.removed} removed; {summary.objects} in the map; "
        f"{visit}{summary.seconds:.1f} s"
    )
    if summary.interrupted:
        click.echo(f"{line} (interrupted: run the same command again to resume)")
        sys.exit(130 if stop["signal"] == signal.SIGINT else 143)
    click.echo(line)
    if summary.frames_done == 0 and summary.frames_skipped > 0 and summary.frames_already == 0:
        raise click.ClickException(
            f"{', '.join(recordings)}: no frame could be mapped, all {summary.frames_skipped} were bad "
            f"(see the warnings); {map_path} is unchanged")


@cli.command("ingest-many")
@click.argument("manifest", type=click.Path(dir_okay=False))
@dask_options
@click.option("--writers", default=4, show_default=True, type=click.IntRange(1, 256), help="Maps written at once, one writer each.")
@click.option("--checkpoint-every", default=50, show_default=True, type=click.IntRange(min=0), help="Commit each map every N frames.")
@click.option("--strict", is_flag=True, help="Stop a recording at its first bad frame instead of skipping it.")
def ingest_many(manifest, dask_spec, dask_batch, writers, checkpoint_every, strict):
    """Ingest the recordings of MANIFEST.yaml into their maps (schemas/manifest.schema.json); a recording that
    fails is reported and the others go on."""
    with stop_on_signals() as stop:
        from ltc_cli.ingest.cluster import cluster_for
        from ltc_cli.ingest.fleet import ingest_many as run, manifest_frames, summary_line, summary_table

        with cluster_for(dask_spec, dask_batch) as cluster, progress_bar("ingest-many", lambda: manifest_frames(manifest)) as progress:
            rows = run(manifest, cluster=cluster, writers=writers, checkpoint_every=checkpoint_every, strict=strict,
                       should_stop=lambda: stop["signal"] is not None, warn=warn_line, progress=progress)
    for line in summary_table(rows):
        click.echo(line)
    click.echo(f"{manifest}: {summary_line(rows)}")
    if stop["signal"] is not None:
        sys.exit(130 if stop["signal"] == signal.SIGINT else 143)
    if any(r.status == "failed" for r in rows):
        sys.exit(1)


def _learnt_rate(session: dict) -> bool:
    """Whether a session learnt v_Other per class from the map (then its v_other is only the prior)."""
    try:
        return bool(json.loads(session.get("settings") or "{}").get("maintenance", {}).get("learn_detection_rate"))
    except (ValueError, AttributeError):
        return False


@cli.command()
@click.argument("map_path", type=click.Path())
@click.option("--format", "fmt", type=click.Choice(["table", "json"]), default="table", show_default=True)
def info(map_path, fmt):
    """Summarise a map: classes, objects, sessions, frames."""
    import numpy as np

    from ltc_cli.map.coverage import seen_area
    from ltc_cli.map.model import ACTIVE, MERGED, REMOVED
    from ltc_cli.map.store import FORMAT, VERSION, load_map, orphan_temp_files

    orphans = orphan_temp_files(map_path)
    for tmp, size in orphans:
        shown = f"{size / 1e6:.1f} MB" if size >= 100_000 else f"{size} bytes"
        click.echo(f"warning: {tmp}: a temporary file ({shown}) left by an interrupted write; "
                   "the next ingest into this map removes it", err=True)
    smap = load_map(map_path, events=False)
    t = smap.objects
    active = np.flatnonzero(t.status == ACTIVE)
    per_class = Counter(smap.classes[int(i)] for i in t.scores[active, :-1].argmax(axis=1)) if len(active) else Counter()
    doc = {
        "map": str(map_path),
        "format": FORMAT,
        "format_version": VERSION,
        "classes": smap.classes,
        "objects": {"active": int(len(active)), "removed": int((t.status == REMOVED).sum()),
                    "merged": int((t.status == MERGED).sum())},
        "per_class": dict(sorted(per_class.items())),
        "frames": len(smap.frame_keys),
        "events": smap.n_events,
        "sessions": [
            {k: s[k] for k in ("started", "finished", "status", "metric", "policy", "frames_done", "frames_skipped",
                               "v_other")}
            | {"frames_still": int(s.get("frames_still") or 0), "visit": max(1, int(s.get("visit") or 0)),
               "v_other_learnt": _learnt_rate(s)}
            | {"sources": json.loads(s["sources"]), "detector": json.loads(s["detector"])["name"]}
            | {"cameras": json.loads(s.get("cameras") or "[]"), "readers": json.loads(s.get("readers") or "[]"),
               "reader_options": _json_list(s.get("reader_options")), "frames": s.get("frames") or "",
               "seen_m2": seen_area(s.get("coverage") or "")}
            for s in smap.sessions
        ],
        "up_rotation": np.asarray(smap.up_rotation).round(6).tolist(),
        "created": smap.created,
        "temp_files": [str(tmp) for tmp, _ in orphans],
    }
    if fmt == "json":
        click.echo(json.dumps(doc, indent=2))
        return
    o = doc["objects"]
    click.echo(f"map          {map_path}  ({FORMAT} v{VERSION}, created {smap.created})")
    click.echo(f"classes      {len(smap.classes)}: {', '.join(smap.classes)}")
    click.echo(f"objects      {o['active']} active, {o['removed']} removed, {o['merged']} merged")
    for name, n in doc["per_class"].items():
        click.echo(f"  {name:<18} {n}")
    up = np.asarray(smap.up_rotation)[2]  # the recording's direction that the map made +z
    tilt = float(np.degrees(np.arccos(np.clip(up[2], -1.0, 1.0))))
    click.echo(f"up           map +z = the recording's ({up[0]:.3f}, {up[1]:.3f}, {up[2]:.3f}), "
               f"{tilt:.1f} deg from its +z")
    click.echo(f"frames       {doc['frames']} ingested; {_plural(doc['events'], 'event')} logged")
    click.echo(f"sessions     {len(smap.sessions)}")
    for i, s in enumerate(doc["sessions"]):
        visit = (f"  visit {s['visit']}" if s["visit"] > 1 else "") + (f"  frames {s['frames']}" if s["frames"] else "")
        still = f", {s['frames_still']} still" if s.get("frames_still") else ""
        click.echo(f"  #{i} {s['started']}  {s['status']:<11} {s['frames_done']} frames ({s['frames_skipped']} skipped"
                   f"{still}){visit}  "
                   f"{s['detector']}/{s['metric']}/{s['policy']} v_other="
                   f"{'learnt per class' if s['v_other_learnt'] else format(s['v_other'], '.3g')}  {', '.join(s['sources'])}")
        for cam in dict.fromkeys(camera_text(c) for c in s["cameras"]):  # each camera once, in order
            click.echo(f"     camera {cam}")
        for given in dict.fromkeys(options_text(o) for o in s["reader_options"] if o):
            click.echo(f"     read with {given}")
        if s["seen_m2"] is not None:
            click.echo(f"     saw {s['seen_m2']:.1f} m2 of floor plan (the places ltc changes compares)")
    click.echo(f"{map_path}: {_plural(o['active'], 'object')} of {_plural(len(per_class), 'class')} from "
               f"{_plural(len(smap.frame_keys), 'frame')} in {_plural(len(smap.sessions), 'session')}")


def _json_list(text) -> list:
    """A session row's JSON list (none in maps written before the column, or if damaged)."""
    try:
        value = json.loads(text or "[]")
    except ValueError:
        return []
    return value if isinstance(value, list) else []


def options_text(options) -> str:
    """Reader options as they are given on the command line (-r KEY=VALUE ...)."""
    if not isinstance(options, dict):
        return ""
    return " ".join(f"-r {k}={json.dumps(v) if not isinstance(v, str) else v}" for k, v in sorted(options.items()))


def camera_text(c: dict) -> str:
    """A session's camera (ingest's camera_record) as one line of ``ltc info``."""
    named = f"  (calibration: {c['camera']})" if c.get("camera") else ""
    noise = f", depth noise {c['depth_noise']:.2g} m at 1 m (measured)" if c.get("depth_noise") is not None else ""
    return (f"{c['width']} x {c['height']}, fx {c['fx']:g} fy {c['fy']:g} cx {c['cx']:g} cy {c['cy']:g}"
            + noise + named)


@cli.command("plugins")
@click.option("--format", "fmt", type=click.Choice(["table", "json"]), default="table", show_default=True)
def plugins_cmd(fmt):
    """List the installed plugins, their hooks and what they register."""
    rows = plugins.describe()
    if fmt == "json":
        click.echo(json.dumps(rows, indent=2))
        return
    for r in rows:
        regs = "; ".join(f"{k}: {', '.join(v)}" for k, v in r["registers"].items() if v)
        click.echo(f"{r['name']:<16} {r['package'] or '':<12} hooks: {', '.join(r['hooks'])}")
        if regs:
            click.echo(f"{'':<16} registers {regs}")
    n = {k: len(plugins.registry(k)) for k in plugins.KINDS}
    click.echo(f"{len(rows)} plugins: " + ", ".join(f"{v} {k}" for k, v in n.items()))


def _floats(text, n_allowed, what, param):
    """"1.5,-2[,0.3]" -> list of floats; a click usage error (exit 2) otherwise."""
    try:
        vals = [float(v) for v in str(text).split(",")]
    except ValueError:
        vals = []
    if len(vals) not in n_allowed or not all(math.isfinite(v) for v in vals):
        raise click.BadParameter(f"expected {what}, not {text!r}", param_hint=param)
    return vals


@cli.command("query")
@click.argument("map_path", type=click.Path())
@click.option("--class", "classes", multiple=True, metavar="NAME", help="Only objects of this class (repeat for several).")
@click.option("--near", metavar="X,Y[,Z]", help="Only objects whose centre is within --radius of this point (2-D with X,Y; 3-D with X,Y,Z), metres.")
@click.option("--radius", type=float, metavar="R", help="Radius for --near, metres.")
@click.option("--min-confidence", type=click.FloatRange(0, 1), metavar="P", help="Only objects whose class score is at least P.")
@click.option("--id", "ids", multiple=True, type=click.IntRange(min=1), metavar="N", help="Only this object id (repeat for several).")
@click.option("--removed", is_flag=True, help="Show the objects maintenance removed, with when and why.")
@click.option("--format", "fmt", type=click.Choice(["table", "json", "csv"]), default="table", show_default=True)
def query_cmd(map_path, classes, near, radius, min_confidence, ids, removed, fmt):
    """List the objects of MAP.h5 that pass every filter given."""
    import csv
    import io

    from ltc_cli.map import query as q
    from ltc_cli.map.store import load_map

    point = _floats(near, (2, 3), "X,Y or X,Y,Z", "--near") if near is not None else None
    if (point is None) != (radius is None):
        raise click.UsageError("--near and --radius go together")
    if radius is not None and not (math.isfinite(radius) and radius >= 0):
        raise click.BadParameter(f"must be >= 0, not {radius}", param_hint="--radius")
    smap = load_map(map_path, events=("removed",) if removed else False)  # only --removed reads events
    spec = q.Query(classes=classes, near=point, radius=radius, min_confidence=min_confidence, ids=ids, removed=removed)
    result = q.select(smap, spec, map_path)
    recs = q.records(smap, result)
    if fmt == "json":
        click.echo(json.dumps(recs, indent=2))
    elif fmt == "csv":
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(q.flat_columns(result))
        w.writerows(q.flat_rows(recs))
        click.echo(buf.getvalue(), nl=False)
    elif recs:
        click.echo("\n".join(q.table_lines(recs, result)))
    kind = "removed objects" if removed else "objects"
    click.echo(f"{map_path}: {len(recs)} of {result.total} {kind}", err=True)


# The commands that look at a map's history and at it in 3D, and those of the tools around the
# mapper (simulate, evaluate, calibrate), join the group from their own modules.
from ltc_cli import cli_tools, cli_views  # noqa: E402,F401


def main():
    # One BLAS thread unless the user says otherwise: ltc's matrix products are small (the YOLO
    # masks, 3x3 rotations), and OpenBLAS's idle workers spin between them (+45 % CPU on a
    # real-detector ingest) and cost ~0.07 s CPU at start-up. Only effective before numpy is first
    # imported, which this module does not do; the ingest also limits them through threadpoolctl.
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    cli(prog_name="ltc")


if __name__ == "__main__":
    main()

"""The ``ltc`` commands that show a map: ``export`` (JSON, GeoJSON, Rerun), ``render`` (top-down
picture), ``changes`` (what changed between visits) and ``view`` (3D, in the Rerun viewer).

Part of the command line (with :mod:`ltc_cli.cli`, whose group they join): the only other code that
prints. Library errors reach the user as one line through the group's handler.
"""

from __future__ import annotations

import csv
import io
import json

import click

from ltc_cli.cli import cli
from ltc_cli.text import SkippedFrames, plural, skipped_breakdown


@cli.command("export")
@click.argument("map_path", type=click.Path())
@click.option("--format", "fmt", type=click.Choice(["json", "geojson", "rrd"]), required=True,
              help="json: everything about every object; geojson: footprints (local metres unless --origin); "
                   "rrd: a Rerun recording of the boxes in 3D (needs ltc[viz]; -o required).")
@click.option("-o", "--output", type=click.Path(dir_okay=False), help="Write here (atomically) instead of stdout.")
@click.option("--origin", metavar="LAT,LON[,HEADING_DEG]",
              help="GeoJSON in WGS84 longitude/latitude: the map origin's latitude and longitude (degrees) and the "
                   "bearing of the map's +y axis (degrees clockwise from true north; default 0).")
def export_cmd(map_path, fmt, output, origin):
    """Export the active objects of MAP.h5 as JSON, GeoJSON (RFC 7946) or a Rerun .rrd file."""
    from ltc_cli.map import export as ex
    from ltc_cli.map.store import load_map

    if fmt == "rrd":
        from ltc_cli.map.rrd import require_rerun, write_rrd

        if not output or origin is not None:
            raise click.UsageError("--format rrd writes a file: give -o FILE.rrd (and no --origin)")
        require_rerun()  # before reading the map: the missing extra is the first thing to hear
        done = write_rrd(output, load_map(map_path))
        click.echo(f"{map_path}: {plural(done['objects'], 'object')} exported as rrd to {output} "
                   f"(open it with: rerun {output})", err=True)
        return

    geo_origin = None
    if origin is not None:
        if fmt != "geojson":
            raise click.UsageError("--origin applies to --format geojson only")
        try:
            geo_origin = ex.parse_origin(origin)
        except ex.ExportError as exc:
            raise click.BadParameter(exc.message, param_hint="--origin") from None
    from ltc_cli.map.export_stream import export_chunks, write_export

    smap = load_map(map_path, events=False)
    chunks = export_chunks(smap, fmt, geo_origin, map_path)
    if output:
        write_export(output, chunks)
    else:
        for chunk in chunks:
            click.echo(chunk, nl=False)
    n = len(smap.active_rows())
    crs = "" if fmt == "json" else (" (WGS84 lon/lat)" if geo_origin else
                                     " (local metres, not lon/lat: give --origin LAT,LON for GIS tools)")
    click.echo(f"{map_path}: {plural(n, 'object')} exported as {fmt}{crs} to {output or 'stdout'}", err=True)


@cli.command("render")
@click.argument("map_path", type=click.Path())
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False), help="The PNG to write.")
@click.option("--ground-truth", "ground_truth", type=click.Path(), metavar="FILE|RECORDING",
              help="ground_truth.json, or a recording folder holding one: drawn beneath as dashed outlines "
                   "(with --recording: thin grey boxes).")
@click.option("--width", default=1200, show_default=True, type=click.IntRange(100, 16384), help="Pixels.")
@click.option("--height", default=900, show_default=True, type=click.IntRange(100, 16384), help="Pixels.")
@click.option("--labels/--no-labels", default=None, help="Label objects 'class #id' (default: when at most 300).")
@click.option("--changes", "show_changes", is_flag=True,
              help="Mark what the latest visit changed (as `ltc changes`): added green, removed red, moved orange.")
@click.option("--since", type=click.IntRange(min=-1), metavar="SESSION", help="With --changes: changes after this session.")
@click.option("--coverage", "show_seen", is_flag=True,
              help="Shade the floor plan the sessions' depth saw (with --changes: the sessions it compares with).")
@click.option("--recording", type=click.Path(), metavar="RECORDING",
              help="Instead of top-down: draw the boxes into frames of this recording, as its camera saw them.")
@click.option("--frames", "frame_list", metavar="I,J,...",
              help="With --recording: the frames (0-based indices) to draw [default: four spread evenly].")
@click.option("--columns", type=click.IntRange(1, 64), default=2, show_default=True, help="With --recording: frames a row.")
@click.option("--scale", type=click.FloatRange(0.05, 4.0), default=1.0, show_default=True,
              help="With --recording: each frame's size against the recording's images.")
@click.option("--id", "ids", type=click.IntRange(min=1), multiple=True, help="With --recording: only this object (repeat).")
@click.option("--format", "reader", help="With --recording: its reader (default: detected).")
@click.option("--reader-option", "-r", "reader_opts", multiple=True, metavar="KEY=VALUE",
              help="With --recording: a reader option (as for ingest).")
@click.pass_context
def render_cmd(ctx, map_path, output, ground_truth, width, height, labels, show_changes, since, show_seen, recording,
               frame_list, columns, scale, ids, reader, reader_opts):
    """Draw MAP.h5 top-down (footprints by class, labels, scale bar, legend) into a picture (PNG, or
    JPEG, WebP, TIFF, BMP by the output's suffix); with --recording, its boxes drawn into that
    recording's frames instead (to see that each box sits on its thing)."""
    from pathlib import Path

    from ltc_cli.map.changes import map_changes
    from ltc_cli.map.coverage import sessions_seen
    from ltc_cli.map.render import load_ground_truth, render_map
    from ltc_cli.map.store import load_map

    if since is not None and not show_changes:
        raise click.UsageError("--since goes with --changes")
    given = {name for name in ("ground_truth", "width", "height", "labels", "show_changes", "show_seen", "frame_list",
                               "columns", "scale", "ids", "reader", "reader_opts")
             if ctx.get_parameter_source(name) == click.core.ParameterSource.COMMANDLINE}
    if recording is not None:
        top_down = sorted(given & {"width", "height", "labels", "show_changes", "show_seen"})
        if top_down:
            flag = {"show_changes": "changes", "show_seen": "coverage"}.get(top_down[0], top_down[0])
            raise click.UsageError(f"--{flag} draws the top-down picture; it does not go with --recording")
        _render_frames(map_path, output, recording, frame_list, columns, scale, ids, reader, reader_opts, ground_truth)
        return
    framed = sorted(given & {"frame_list", "columns", "scale", "ids", "reader", "reader_opts"})
    if framed:
        option = {"frame_list": "frames", "ids": "id", "reader": "format", "reader_opts": "reader-option"}
        raise click.UsageError(f"--{option.get(framed[0], framed[0])} goes with --recording")
    smap = load_map(map_path, events=show_changes)  # only --changes reads the event log
    gt = load_ground_truth(ground_truth) if ground_truth else None
    report = map_changes(smap, since, map_path=map_path) if show_changes else None
    seen = None
    if show_seen:
        seen = sessions_seen(smap.sessions[: report.since + 1] if report else smap.sessions, strict=False)
        if seen is None:
            raise click.ClickException(f"{map_path}: its sessions kept no record of where they looked "
                                       "(maps written before ltc kept it)")
    res = render_map(smap, output, ground_truth=gt, width=width, height=height, labels=labels,
                     map_name=Path(map_path).name, changes=report.changes if report else None, seen=seen)
    extra = f", {res.ground_truth} ground-truth boxes" if gt is not None else ""
    extra += f", {len(seen[0]) * seen[1] ** 2:.1f} m2 seen" if seen is not None else ""
    if res.changes is not None:
        extra += ", changes: " + ", ".join(f"{n} {k}" for k, n in res.changes.items())
    fmt = "" if res.format == "PNG" else f" {res.format}"
    click.echo(f"{output}: {res.width}x{res.height} px{fmt}, {plural(res.objects, 'object')}{extra}")


def _render_frames(map_path, output, recording, frame_list, columns, scale, ids, reader, reader_opts,
                   ground_truth) -> None:
    from ltc_cli.cli import reader_options
    from ltc_cli.config import load_config
    from ltc_cli.map.render import load_ground_truth
    from ltc_cli.map.render_frames import default_frames, frame_sheet
    from ltc_cli.map.store import load_map
    from ltc_cli.recordings.open import open_as_ingested

    smap = load_map(map_path, events=False)
    rec = open_as_ingested(recording, smap.sessions, reader, reader_options(reader_opts))
    n = len(rec.frames)
    if frame_list:
        try:
            indices = [int(x) for x in frame_list.split(",") if x.strip()]
        except ValueError:
            raise click.BadParameter(f"{frame_list!r} is not a list of frame indices (e.g. 0,50,100)",
                                     param_hint="--frames") from None
        bad = [i for i in indices if not 0 <= i < n]
        if bad or not indices:
            raise click.BadParameter(f"frame {bad[0] if bad else frame_list!r} is not in the recording "
                                     f"(frames 0..{n - 1})", param_hint="--frames")
        indices = list(dict.fromkeys(indices))
    else:
        indices = default_frames(n)
    missing = sorted(set(ids) - {int(r) + 1 for r in smap.active_rows()})
    if missing:
        raise click.BadParameter(f"object {missing[0]} is not in the map (or was removed)", param_hint="--id")
    # Boxes as far as the depth reaches: beyond it they stand behind walls, and a big map's far
    # rooms would bury the frame (a recording's own range, else the settings' default).
    max_depth = rec.depth_range[1] if rec.depth_range else load_config(None)["modeling"]["max_depth"]
    truth = load_ground_truth(ground_truth) if ground_truth else None
    res = frame_sheet(smap, rec, indices, output, columns=columns, scale=scale, ids=set(ids) or None,
                      on_skip=lambda i, exc: click.echo(f"warning: frame {i} skipped: {exc}", err=True),
                      max_depth=max_depth, truth=truth)
    shown = len(ids) if ids else len(smap.active_rows())
    click.echo(f"{output}: {res.width}x{res.height} px, {plural(len(res.frames), 'frame')} of {recording}, "
               f"{plural(shown, 'object')} ({res.in_view} in view within {max_depth:g} m)"
               + (f", {plural(len(truth), 'ground-truth box')} beneath" if truth is not None else ""))


@cli.command("changes")
@click.argument("map_path", type=click.Path())
@click.option("--since", type=click.IntRange(min=-1), metavar="SESSION",
              help="Compare with the map at the end of this session (0-based, as `ltc info` numbers them; "
                   "-1: an empty map). Default: the session before the last, i.e. what the latest visit changed.")
@click.option("--move-radius", type=click.FloatRange(min=0), default=None, metavar="M",
              help="Largest distance (m) between a removal and an addition of one class that is reported as a move "
                   "[default: 6].")
@click.option("--format", "fmt", type=click.Choice(["table", "json", "csv"]), default="table", show_default=True)
def changes_cmd(map_path, since, move_radius, fmt):
    """List the objects added, removed and moved since a session (from the map's event log)."""
    from ltc_cli.map import changes as ch
    from ltc_cli.map.store import load_map

    smap = load_map(map_path)
    radius = ch.MOVE_RADIUS if move_radius is None else move_radius
    report = ch.map_changes(smap, since, move_radius=radius, map_path=map_path)
    if fmt == "json":
        doc = {"map": str(map_path), "since": report.since, "sessions": report.sessions,
               "move_radius": radius, "replaced": report.replaced, "confirmed": report.confirmed,
               "first_seen": report.first_seen,
               "changes": [c.as_dict() for c in report.changes]}
        click.echo(json.dumps(doc, indent=2))
    elif fmt == "csv":
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(ch.COLUMNS)
        w.writerows(ch.flat_rows(report))
        click.echo(buf.getvalue(), nl=False)
    elif report.changes:
        click.echo("\n".join(ch.table_lines(report)))
    later = report.sessions - 1 - report.since
    counts = ", ".join(f"{report.count(k)} {k}" for k in ch.KINDS)
    kept = f"; {plural(report.replaced, 'object')} re-identified in place" if report.replaced else ""
    if report.confirmed:
        kept += f"; {plural(report.confirmed, 'object')} an earlier visit named once, confirmed"
    if report.first_seen:
        kept += f"; {plural(report.first_seen, 'object')} first seen where no earlier session looked"
    click.echo(f"{map_path}: since session {report.since} ({plural(max(later, 0), 'later session')}): "
               f"{counts}{kept}", err=True)


@cli.command("view")
@click.argument("map_path", type=click.Path())
@click.argument("recording", required=False, type=click.Path())
@click.option("--format", "reader", help="Recording reader (default: detected).")
@click.option("--reader-option", "-r", "reader_opts", multiple=True, metavar="KEY=VALUE", help="A reader option (as for ingest).")
@click.option("--every", type=click.IntRange(min=1), default=1, show_default=True, help="Log every N-th frame of RECORDING.")
@click.option("--no-images", is_flag=True, help="Log the camera path only, not the images.")
@click.option("--save", type=click.Path(dir_okay=False), metavar="FILE.rrd",
              help="Write the .rrd file instead of opening the viewer (e.g. on a machine without a display).")
def view_cmd(map_path, recording, reader, reader_opts, every, no_images, save):
    """Show MAP.h5 in 3D in the Rerun viewer: the boxes with class and id, and with RECORDING the
    camera path and its images on a timeline (needs ltc[viz])."""
    import os
    import sys

    from ltc_cli.cli import reader_options
    from ltc_cli.map import rrd
    from ltc_cli.map.render_frames import recording_to_map
    from ltc_cli.map.store import load_map
    from ltc_cli.recordings.open import open_as_ingested

    rrd.require_rerun()
    smap = load_map(map_path)
    rec = open_as_ingested(recording, smap.sessions, reader, reader_options(reader_opts)) if recording else None
    T = recording_to_map(smap, rec) if rec is not None else None

    skips = SkippedFrames(lambda message: click.echo(f"warning: {message}", err=True))

    def frames(n: int) -> str:
        skipped = sum(skips.counts.values())
        return plural(n, "frame") + (f" ({skipped} skipped: {skipped_breakdown(skips.counts)})" if skipped else "")

    if save:
        done = rrd.write_rrd(save, smap, rec, T, every, not no_images, skips)
        click.echo(f"{save}: {plural(done['objects'], 'object')}, {frames(done['frames'])} (open it with: rerun {save})")
        return
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise click.ClickException("no display to open the viewer on: write the file with --save map.rrd "
                                   "and open it where there is one (rerun map.rrd)")
    stream = rrd.new_stream(os.path.basename(map_path))
    stream.spawn()
    n_obj = rrd.log_map(stream, smap)
    n_frames = rrd.log_recording(stream, rec, T, every, not no_images, skips) if rec is not None else 0
    stream.flush()
    click.echo(f"{map_path}: {plural(n_obj, 'object')}, {frames(n_frames)} sent to the Rerun viewer")

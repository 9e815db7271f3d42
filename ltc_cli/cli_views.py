"""The ``ltc`` commands that look at a map's history and at it in 3D: ``changes`` and ``view``.

Part of the command line (with :mod:`ltc_cli.cli`, whose group they join): the only other code that
prints. Library errors reach the user as one line through the group's handler.
"""

from __future__ import annotations

import csv
import io
import json

import click

from ltc_cli.cli import cli


def plural(n: int, word: str) -> str:
    return f"{n} {word}{'' if n == 1 else 's'}"


@cli.command("changes")
@click.argument("map_path", type=click.Path())
@click.option("--since", type=click.IntRange(min=-1), metavar="SESSION",
              help="Compare with the map at the end of this session (0-based, as `ltc info` numbers them; "
                   "-1: an empty map). Default: the session before the last, i.e. what the latest visit changed.")
@click.option("--move-radius", type=click.FloatRange(min=0), default=None, metavar="M",
              help="Largest distance (m) between a removal and an addition of one class that is reported as a move "
                   "[default: 4].")
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
               "move_radius": radius, "replaced": report.replaced,
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
    from ltc_cli.map.store import load_map
    from ltc_cli.recordings.open import open_recording

    rrd.require_rerun()
    smap = load_map(map_path)
    rec = open_recording(recording, reader, reader_options(reader_opts)) if recording else None
    T = rrd.recording_to_map(smap, rec) if rec is not None else None

    def warn(message):
        click.echo(f"warning: {message}", err=True)

    if save:
        done = rrd.write_rrd(save, smap, rec, T, every, not no_images, warn)
        click.echo(f"{save}: {plural(done['objects'], 'object')}, {plural(done['frames'], 'frame')} "
                   f"(open it with: rerun {save})")
        return
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise click.ClickException("no display to open the viewer on: write the file with --save map.rrd "
                                   "and open it where there is one (rerun map.rrd)")
    stream = rrd.new_stream(os.path.basename(map_path))
    stream.spawn()
    n_obj = rrd.log_map(stream, smap)
    n_frames = rrd.log_recording(stream, rec, T, every, not no_images, warn) if rec is not None else 0
    stream.flush()
    click.echo(f"{map_path}: {plural(n_obj, 'object')}, {plural(n_frames, 'frame')} sent to the Rerun viewer")

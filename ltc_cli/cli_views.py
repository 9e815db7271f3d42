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

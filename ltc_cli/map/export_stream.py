"""The JSON and GeoJSON exports written as text in chunks, without a dict per object.

``dumps(export_json(smap))`` holds a dict per object and the whole text at once: a 100,000-object
export took 3.3 s CPU and 711-776 MiB. :func:`export_chunks` yields the same bytes (a test compares
them) a few thousand objects at a time, their numbers formatted with numpy
(:mod:`ltc_cli.map.json_text`), and :func:`write_export` writes the chunks to a file atomically.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from ltc_cli.fileio import write_chunks_atomic
from ltc_cli.map import json_text as jt
from ltc_cli.map.export import (DEG_DECIMALS, METRE_DECIMALS, VALUE_DECIMALS, ExportError, dumps,
                                export_geojson, export_json, geojson_columns, geojson_head, head_text,
                                json_columns, json_head)
from ltc_cli.map.model import SemanticMap
from ltc_cli.map.query import paused_gc

CHUNK = 4096  # objects per chunk: about 10 MB of working arrays


def export_chunks(smap: SemanticMap, fmt: str, origin=None, map_path=None, chunk: int = CHUNK) -> Iterator[bytes]:
    """The UTF-8 text of ``dumps(export_json(...))`` (``fmt`` "json") or of
    ``dumps(export_geojson(...))`` ("geojson"), in pieces."""
    names = smap.class_vector_names
    if len(set(names)) != len(names):
        # Repeated class names collapse in the scores dict; rare enough to take the dict path.
        doc = export_json(smap, map_path) if fmt == "json" else export_geojson(smap, origin, map_path)
        yield dumps(doc).encode("utf-8")
        return
    if fmt == "json":
        cols = json_columns(smap)
        doc, line = json_head(smap, map_path), _json_line
    else:
        cols = geojson_columns(smap, origin)
        doc, line = geojson_head(smap, origin, map_path, cols["bbox"]), _geojson_line
    lead, _, tail = head_text(doc)
    yield lead.encode("utf-8")
    n = len(cols["id"])
    for start in range(0, n, chunk):
        part = {k: (v[start:start + chunk] if isinstance(v, np.ndarray) else v) for k, v in cols.items()}
        k = len(part["id"])
        # Each line: two spaces, the object, then ",\n" (or "\n" after the last object of all).
        sep = np.tile(np.frombuffer(b",\n", np.uint8), (k, 1)), np.ones((k, 2), bool)
        if start + k == n:
            sep[1][-1, 0] = False
        with paused_gc():
            yield jt.pack(line(part, names, jt.lit("  "), sep))
    yield tail.encode("utf-8")


def _seen(cols):
    return (jt.lit(',"first_seen":{"session":'), jt.integers(cols["first_session"]), jt.lit(',"frame":'),
            jt.integers(cols["first_frame"]), jt.lit('},"last_seen":{"session":'), jt.integers(cols["last_session"]),
            jt.lit(',"frame":'), jt.integers(cols["last_frame"]), jt.lit("}"))


def _common(cols, names):
    """id .. size: the members both exports start an object's properties with."""
    d = VALUE_DECIMALS
    return (jt.lit('{"id":'), jt.integers(cols["id"]), jt.lit(',"class":'), jt.texts(cols["class"], names),
            jt.lit(',"confidence":'), jt.decimals(cols["confidence"], d),
            jt.lit(',"scores":'), jt.seq(jt.decimals(cols["scores"], d), names),
            jt.lit(',"center":'), jt.seq(jt.decimals(cols["center"], d)),
            jt.lit(',"yaw":'), jt.decimals(cols["yaw"], d), jt.lit(',"size":'), jt.seq(jt.decimals(cols["size"], d)))


def _json_line(cols, names, lead, sep):
    """The objects' lines, ``lead`` before and ``sep`` after each (one cat: no copy of the lines)."""
    d = VALUE_DECIMALS
    return jt.cat(lead, *_common(cols, names), jt.lit(',"corners":'), jt.seq(jt.seq(jt.decimals(cols["corners"], d))),
                  jt.lit(',"visible":'), jt.seq(jt.booleans(cols["visible"])),
                  jt.lit(',"defined":'), jt.booleans(cols["defined"]), jt.lit(',"n_det":'), jt.integers(cols["n_det"]),
                  jt.lit(',"n_nondet":'), jt.integers(cols["n_nondet"]), *_seen(cols), jt.lit("}"), sep)


def _geojson_line(cols, names, lead, sep):
    d = VALUE_DECIMALS
    places = METRE_DECIMALS if cols["bearing"] is None else DEG_DECIMALS
    bearing = () if cols["bearing"] is None else (jt.lit(',"x_axis_bearing_deg":'), jt.decimals(cols["bearing"], d))
    return jt.cat(lead, jt.lit('{"type":"Feature","id":'), jt.integers(cols["id"]),
                  jt.lit(',"geometry":{"type":"Polygon","coordinates":['),
                  jt.seq(jt.seq(jt.decimals(cols["coords"], places))), jt.lit(']},"properties":'),
                  *_common(cols, names), jt.lit(',"z_min":'), jt.decimals(cols["z_min"], d),
                  jt.lit(',"z_max":'), jt.decimals(cols["z_max"], d), jt.lit(',"height":'),
                  jt.decimals(cols["size"][:, 2], d), jt.lit(',"defined":'), jt.booleans(cols["defined"]),
                  jt.lit(',"n_det":'), jt.integers(cols["n_det"]), jt.lit(',"n_nondet":'),
                  jt.integers(cols["n_nondet"]), *_seen(cols), *bearing, jt.lit("}}"), sep)


def write_export(path, chunks) -> None:
    """Write the chunks to ``path`` atomically (temporary file beside it, fsync, ``os.replace``)."""
    try:
        write_chunks_atomic(path, chunks)
    except OSError as exc:
        raise ExportError(f"cannot write the export ({exc.strerror})", path) from None

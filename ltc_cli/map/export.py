"""Exports of a map as plain dicts: JSON (everything about every object) and GeoJSON footprints.

No click, no HDF5: the functions take a loaded :class:`~ltc_cli.mapping.SemanticMap` and return
JSON-ready dicts; :func:`write_atomic` writes text the way the map store writes maps (temporary file
beside the target, fsync, ``os.replace``), so a reader never sees half an export.

Georeferencing (GeoJSON with an origin)
---------------------------------------
The map frame is local and metric (x, y horizontal, z up). Given the geodetic position of the map
origin (latitude, longitude in degrees on the WGS84 ellipsoid) and a *heading*, map points go to
WGS84 in two steps:

1. Rotate map (x, y) into the local East-North-Up frame at the origin. ``heading_deg`` is the
   compass bearing of the map's +y axis: degrees clockwise from true north, seen from above. So
   heading 0 means +y points north and +x east (the map frame *is* ENU); heading 90 means +y points
   east and +x south. In formulas, with h = heading in radians::

       east  =  x cos h + y sin h
       north = -x sin h + y cos h

2. Take (east, north, up = 0) in the plane tangent to the ellipsoid at the origin (height 0) to
   ECEF, and ECEF to geodetic latitude / longitude (exact iteration, converged far below 0.1 mm).
   The only approximation is the tangent plane itself: a point d metres from the origin is d^2 / 2R
   above the ellipsoid (0.8 mm at 100 m), which moves its latitude / longitude by far less than that.

Coordinates are rounded to 1e-9 degrees (about 0.1 mm) or to 0.1 mm in local metres.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ltc_cli import __version__
from ltc_cli.fileio import write_text_atomic
from ltc_cli.errors import LtcError
from ltc_cli.geometry.boxes import box_corners
from ltc_cli.map.model import SemanticMap
from ltc_cli.map.query import classify, paused_gc

JSON_FORMAT = "ltc-map-export/1"
GEOJSON_FORMAT = "ltc-geojson/1"
CRS_LOCAL = "local-metres"
CRS_WGS84 = "urn:ogc:def:crs:OGC::CRS84"  # WGS84 longitude, latitude (RFC 7946's only CRS)

# WGS84 ellipsoid.
WGS84_A = 6378137.0
WGS84_F = 1.0 / 298.257223563
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)

DEG_DECIMALS = 9    # 1e-9 deg ~ 0.11 mm of latitude
METRE_DECIMALS = 4  # 0.1 mm, the same resolution in local coordinates
VALUE_DECIMALS = 6  # metres / radians / probabilities in properties and the JSON export


#: Written into local-metre GeoJSON: RFC 7946 readers (QGIS, geojson.io, ...) take every position as
#: WGS84 longitude / latitude, so a room in metres shows up as a speck near (0 deg, 0 deg).
LOCAL_NOTE = ("coordinates are map-frame metres [x, y], NOT longitude/latitude: GIS tools will draw them "
              "near (0, 0) degrees off the coast of Africa; export with --origin LAT,LON[,HEADING_DEG] "
              "for WGS84")


class ExportError(LtcError):
    """An export that cannot be made (bad origin, unwritable output file)."""


# -- geodesy ---------------------------------------------------------------------------------------

def geodetic_to_ecef(lat_deg, lon_deg, h=0.0) -> np.ndarray:
    """WGS84 geodetic (degrees, degrees, metres; broadcastable) -> ECEF (..., 3) metres."""
    lat, lon = np.radians(lat_deg), np.radians(lon_deg)
    h = np.asarray(h, dtype=np.float64)
    sl = np.sin(lat)
    n = WGS84_A / np.sqrt(1.0 - WGS84_E2 * sl * sl)  # prime-vertical radius of curvature
    x = (n + h) * np.cos(lat) * np.cos(lon)
    y = (n + h) * np.cos(lat) * np.sin(lon)
    z = (n * (1.0 - WGS84_E2) + h) * sl
    return np.stack(np.broadcast_arrays(x, y, z), axis=-1)


def ecef_to_geodetic(xyz) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ECEF (..., 3) metres -> (lat_deg, lon_deg, h) on WGS84.

    Fixed-point iteration on tan(lat) = (Z + e^2 N sin(lat)) / p, which is well conditioned at any
    latitude (including the poles, where p -> 0) and gains several digits per step near the
    surface; 6 steps leave errors below 1e-12 rad.
    """
    xyz = np.asarray(xyz, dtype=np.float64)
    x, y, z = xyz[..., 0], xyz[..., 1], xyz[..., 2]
    lon = np.arctan2(y, x)
    p = np.hypot(x, y)
    lat = np.arctan2(z, p * (1.0 - WGS84_E2))
    for _ in range(6):
        sl = np.sin(lat)
        n = WGS84_A / np.sqrt(1.0 - WGS84_E2 * sl * sl)
        lat = np.arctan2(z + WGS84_E2 * n * sl, p)
    sl, cl = np.sin(lat), np.cos(lat)
    # Height valid at every latitude (no division by cos(lat)).
    h = p * cl + z * sl - WGS84_A * np.sqrt(1.0 - WGS84_E2 * sl * sl)
    return np.degrees(lat), np.degrees(lon), h


def _enu_basis(lat_deg, lon_deg) -> np.ndarray:
    """R (3, 3) whose rows are the ECEF directions of east, north and up at a geodetic point."""
    lat, lon = math.radians(lat_deg), math.radians(lon_deg)
    sl, cl, so, co = math.sin(lat), math.cos(lat), math.sin(lon), math.cos(lon)
    return np.array([[-so, co, 0.0], [-sl * co, -sl * so, cl], [cl * co, cl * so, sl]])


def enu_to_geodetic(enu, lat0_deg, lon0_deg, h0=0.0):
    """Local ENU (..., 3) metres at the origin (lat0, lon0, h0) -> (lat_deg, lon_deg, h)."""
    enu = np.asarray(enu, dtype=np.float64)
    ecef = geodetic_to_ecef(lat0_deg, lon0_deg, h0) + enu @ _enu_basis(lat0_deg, lon0_deg)
    return ecef_to_geodetic(ecef)


def geodetic_to_enu(lat_deg, lon_deg, h, lat0_deg, lon0_deg, h0=0.0) -> np.ndarray:
    """Inverse of :func:`enu_to_geodetic`: geodetic points -> ENU (..., 3) metres at the origin."""
    d = geodetic_to_ecef(lat_deg, lon_deg, h) - geodetic_to_ecef(lat0_deg, lon0_deg, h0)
    return d @ _enu_basis(lat0_deg, lon0_deg).T


def map_xy_to_enu(xy, heading_deg: float) -> np.ndarray:
    """Map-frame (..., 2) -> (east, north) (..., 2); heading = bearing of the map's +y axis."""
    h = math.radians(heading_deg)
    c, s = math.cos(h), math.sin(h)
    xy = np.asarray(xy, dtype=np.float64)
    x, y = xy[..., 0], xy[..., 1]
    return np.stack([x * c + y * s, -x * s + y * c], axis=-1)


def map_xy_to_lonlat(xy, origin) -> np.ndarray:
    """Map-frame points (..., 2) -> (..., 2) [longitude, latitude] degrees (GeoJSON order).

    origin: (lat_deg, lon_deg, heading_deg); see the module docstring for the convention.
    """
    lat0, lon0, heading = origin
    en = map_xy_to_enu(xy, heading)
    enu = np.concatenate([en, np.zeros(en.shape[:-1] + (1,))], axis=-1)
    lat, lon, _ = enu_to_geodetic(enu, lat0, lon0, 0.0)
    lon = (lon + 180.0) % 360.0 - 180.0  # [-180, 180)
    return np.stack([lon, lat], axis=-1)


def parse_origin(text: str) -> tuple[float, float, float]:
    """"LAT,LON[,HEADING_DEG]" -> (lat, lon, heading); heading defaults to 0 (+y north)."""
    try:
        vals = [float(v) for v in str(text).split(",")]
    except ValueError:
        vals = []
    if len(vals) not in (2, 3) or not all(math.isfinite(v) for v in vals):
        raise ExportError(f"origin must be LAT,LON or LAT,LON,HEADING_DEG in degrees, not {text!r}")
    lat, lon = vals[0], vals[1]
    heading = vals[2] if len(vals) == 3 else 0.0
    if not -90.0 < lat < 90.0:  # at a pole "north" (the heading's reference) does not exist
        raise ExportError(f"origin latitude must be strictly between -90 and 90, not {lat}")
    if not -180.0 <= lon <= 180.0:
        raise ExportError(f"origin longitude must be within [-180, 180], not {lon}")
    return lat, lon, heading % 360.0


# -- the exports -----------------------------------------------------------------------------------

def _json_or_text(text):
    try:
        return json.loads(text) if isinstance(text, str) and text else text
    except ValueError:
        return text


def sessions_summary(smap: SemanticMap) -> list[dict]:
    """One small dict per ingest session (index, times, status, sources, plugins, frames)."""
    out = []
    for i, s in enumerate(smap.sessions):
        det = _json_or_text(s.get("detector", ""))
        sources = _json_or_text(s.get("sources", "[]"))
        cameras = _json_or_text(s.get("cameras") or "[]")
        out.append({
            "session": i, "started": s.get("started", ""), "finished": s.get("finished", ""),
            "status": s.get("status", ""),
            "sources": sources if isinstance(sources, list) else [str(sources)],
            "detector": det.get("name") if isinstance(det, dict) else (str(det) if det else None),
            "metric": s.get("metric", ""), "policy": s.get("policy", ""),
            "v_other": float(s["v_other"]) if s.get("v_other") is not None else None,
            "frames_done": int(s.get("frames_done", 0) or 0),
            "frames_skipped": int(s.get("frames_skipped", 0) or 0),
            "frames_still": int(s.get("frames_still", 0) or 0),
            "frames": str(s.get("frames") or ""),
            "cameras": cameras if isinstance(cameras, list) else [],  # none in maps written before
        })
    return out


def _active(smap: SemanticMap):
    rows = smap.active_rows()
    cls_idx, conf = classify(smap)
    return rows, cls_idx[rows], conf[rows]


def export_json(smap: SemanticMap, map_path=None) -> dict:
    """The JSON export (schemas/export.schema.json): metadata, classes and every active object.

    Each object: id, class, confidence, scores {class: p, ..., other: p}, center [x, y, z] (m, map
    frame), yaw (rad about z), size [sx, sy, sz] (m), corners (8 x [x, y, z]; bottom ring 0-3
    counter-clockwise from above, then the top ring), visible (8 bools), defined, n_det, n_nondet,
    first_seen / last_seen {session, frame}. (:mod:`ltc_cli.map.export_stream` writes the same as
    text, streamed.)
    """
    with paused_gc():
        cols = json_columns(smap)
        return {**json_head(smap, map_path), "objects": _json_objects(cols, smap.class_vector_names)}


def export_geojson(smap: SemanticMap, origin=None, map_path=None) -> dict:
    """The GeoJSON export (RFC 7946; schemas/geojson-export.schema.json).

    A FeatureCollection with one Feature per active object: its XY footprint as a Polygon with one
    closed, counter-clockwise exterior ring of 5 positions (the bottom corners 0-3, then corner 0
    again). Coordinates are map-frame metres [x, y] without ``origin`` (top-level member
    ``"ltc:crs": "local-metres"``), or [longitude, latitude] in WGS84 degrees with
    ``origin = (lat_deg, lon_deg, heading_deg)`` (see the module docstring). Properties: id, class,
    confidence, scores, center (map metres), yaw, size, z_min, z_max, height, defined, n_det,
    n_nondet, first_seen, last_seen; with an origin also ``x_axis_bearing_deg``, the compass bearing
    of the box's own x axis in [0, 180) (a box is the same after a half turn).
    """
    with paused_gc():
        cols = geojson_columns(smap, origin)
        features = _geojson_features(cols, smap.class_vector_names)
        return geojson_head(smap, origin, map_path, cols["bbox"], features)


def json_columns(smap: SemanticMap) -> dict:
    """The values of the JSON export's objects, as arrays (K active objects), rounded as written."""
    t = smap.objects
    rows, cls_idx, conf = _active(smap)
    d = VALUE_DECIMALS
    return {
        "id": t.ids[rows], "class": cls_idx, "confidence": conf.round(d), "scores": t.scores[rows].round(d),
        "center": t.center[rows].round(d), "yaw": t.yaw[rows].round(d), "size": t.size[rows].round(d),
        "corners": box_corners(t.center[rows], t.yaw[rows], t.size[rows]).round(d),
        "visible": t.visible[rows], "defined": t.defined[rows], "n_det": t.n_det[rows],
        "n_nondet": t.n_nondet[rows], "first_session": t.first_session[rows], "first_frame": t.first_frame[rows],
        "last_session": t.last_session[rows], "last_frame": t.last_frame[rows],
    }


SEEN = ("first_session", "first_frame", "last_session", "last_frame")


def _json_objects(cols: dict, names: list[str]) -> list[dict]:
    keys = ["id", "class", "confidence", "scores", "center", "yaw", "size", "corners", "visible", "defined",
            "n_det", "n_nondet", *SEEN]
    objects = []
    for oid, ci, cf, sc, c, yaw, s, cn, vis, dfd, nd, nn, fs, ff, ls, lf in zip(*(cols[k].tolist() for k in keys)):
        objects.append({
            "id": oid, "class": names[ci], "confidence": cf, "scores": dict(zip(names, sc)),
            "center": c, "yaw": yaw, "size": s, "corners": cn, "visible": vis, "defined": dfd,
            "n_det": nd, "n_nondet": nn,
            "first_seen": {"session": fs, "frame": ff}, "last_seen": {"session": ls, "frame": lf},
        })
    return objects


def json_head(smap: SemanticMap, map_path=None) -> dict:
    """The JSON export without its objects (``"objects": []``, last)."""
    return {
        "format": JSON_FORMAT,
        "map": {
            "file": None if map_path is None else Path(map_path).name,
            "format": "ltc-map", "format_version": 1, "created": smap.created,
            "up_rotation": np.asarray(smap.up_rotation, dtype=np.float64).round(9).tolist(),
            "frames": len(smap.frame_keys), "sessions": sessions_summary(smap),
        },
        "ltc_version": __version__,
        "units": {"length": "m", "angle": "rad"},
        "frame": "map: right-handed, z up; yaw about z, counter-clockwise from +x",
        "classes": list(smap.classes),
        "objects": [],
    }


def geojson_columns(smap: SemanticMap, origin=None) -> dict:
    """The values of the GeoJSON export's features, as arrays (K active objects), rounded as
    written: ``coords`` (K, 5, 2) closed rings, ``bearing`` (or None) and the ``bbox`` list."""
    t = smap.objects
    rows, cls_idx, conf = _active(smap)
    d = VALUE_DECIMALS
    center, size, yaw = t.center[rows], t.size[rows], t.yaw[rows]
    ring = box_corners(center, yaw, size)[:, :4, :2]  # (K, 4, 2), counter-clockwise from above
    if origin is None:
        coords = ring.round(METRE_DECIMALS)
    else:
        coords = map_xy_to_lonlat(ring, origin).round(DEG_DECIMALS)
    # Close each ring with an exact copy of its first position (RFC 7946 3.1.6).
    coords = np.concatenate([coords, coords[:, :1]], axis=1)
    bbox = None
    if len(coords):
        lo, hi = coords.reshape(-1, 2).min(axis=0), coords.reshape(-1, 2).max(axis=0)
        bbox = [float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])]
    bearing = None
    if origin is not None:
        # Rounded, then wrapped again: 179.9999999 must not round up to 180.
        bearing = np.mod(np.mod(origin[2] + 90.0 - np.degrees(yaw), 180.0).round(d), 180.0)
    return {
        "id": t.ids[rows], "class": cls_idx, "confidence": conf.round(d), "scores": t.scores[rows].round(d),
        "center": center.round(d), "yaw": yaw.round(d), "size": size.round(d),
        "z_min": (center[:, 2] - size[:, 2] / 2).round(d), "z_max": (center[:, 2] + size[:, 2] / 2).round(d),
        "defined": t.defined[rows], "n_det": t.n_det[rows], "n_nondet": t.n_nondet[rows],
        "first_session": t.first_session[rows], "first_frame": t.first_frame[rows],
        "last_session": t.last_session[rows], "last_frame": t.last_frame[rows],
        "coords": coords, "bearing": bearing, "bbox": bbox,
    }


def _geojson_features(cols: dict, names: list[str]) -> list[dict]:
    keys = ["id", "class", "confidence", "scores", "center", "yaw", "size", "z_min", "z_max", "defined", "n_det",
            "n_nondet", *SEEN, "coords"]
    bearing = None if cols["bearing"] is None else cols["bearing"].tolist()
    features = []
    for k, (oid, ci, cf, sc, c, yw, s, z0, z1, dfd, nd, nn, fs, ff, ls, lf, ring_k) in enumerate(
            zip(*(cols[key].tolist() for key in keys))):
        props = {
            "id": oid, "class": names[ci], "confidence": cf, "scores": dict(zip(names, sc)),
            "center": c, "yaw": yw, "size": s, "z_min": z0, "z_max": z1, "height": s[2],
            "defined": dfd, "n_det": nd, "n_nondet": nn,
            "first_seen": {"session": fs, "frame": ff}, "last_seen": {"session": ls, "frame": lf},
        }
        if bearing is not None:
            props["x_axis_bearing_deg"] = bearing[k]
        features.append({"type": "Feature", "id": oid,
                         "geometry": {"type": "Polygon", "coordinates": [ring_k]}, "properties": props})
    return features


def geojson_head(smap: SemanticMap, origin, map_path, bbox, features=()) -> dict:
    """The GeoJSON document around ``features`` (``bbox`` from :func:`geojson_columns`)."""
    doc = {
        "type": "FeatureCollection",
        "ltc:format": GEOJSON_FORMAT,
        "ltc:crs": CRS_LOCAL if origin is None else CRS_WGS84,
        **({"ltc:note": LOCAL_NOTE} if origin is None else {}),
        "ltc:origin": None if origin is None else {
            "lat": origin[0], "lon": origin[1], "heading_deg": origin[2],
            "convention": "heading_deg = bearing of the map's +y axis, degrees clockwise from true "
                          "north; map (x, y) rotated into east/north, then WGS84 from the tangent "
                          "plane at the origin (height 0)",
        },
        "ltc:map": None if map_path is None else Path(map_path).name,
        "ltc:classes": list(smap.classes),
        "features": list(features),
    }
    if bbox is not None:
        doc["bbox"] = bbox  # RFC 7946 5: [west, south, east, north] (or [xmin, ymin, xmax, ymax])
    return doc


def head_text(doc: dict) -> tuple[str, str, str]:
    """(text before the first item, the items' key, text after the last item) of :func:`dumps`."""
    key = "features" if "features" in doc else "objects"
    head = {k: v for k, v in doc.items() if k != key}
    text = json.dumps(head, indent=1, ensure_ascii=False, allow_nan=False)
    lead = text[:-1].rstrip() + ("," if head else "")
    return f'{lead}\n "{key}": [\n', key, " ]\n}\n"


def dumps(doc: dict) -> str:
    """JSON text with the metadata indented and one object / feature per line.

    Fully indented, a 100,000-object export is millions of lines of single numbers; one compact
    line per object keeps it greppable, diffable and about a third of the size.
    """
    lead, key, tail = head_text(doc)
    compact = json.JSONEncoder(separators=(",", ":"), ensure_ascii=False, allow_nan=False)
    body = ",\n".join("  " + compact.encode(it) for it in doc.get(key, []))
    return f'{lead}{body}{chr(10) if body else ""}{tail}'


def write_atomic(path, text: str) -> None:
    """Write ``text`` to ``path`` atomically: temporary file beside it, fsync, ``os.replace``."""
    try:
        write_text_atomic(path, text)
    except OSError as exc:
        raise ExportError(f"cannot write the export ({exc.strerror})", path) from None

"""ltc export: JSON and GeoJSON validate against their schemas; footprints are valid closed
counter-clockwise polygons of the right area (checked with shapely); WGS84 coordinates agree with
an independent textbook formula and round-trip to map metres within 1 cm over 100 m."""

import json
import math
import time

import numpy as np
import pytest
from click.testing import CliRunner
from shapely.geometry import Polygon, shape

from ltc_cli.map import export as ex
from ltc_cli.cli import cli
from ltc_cli.geometry.boxes import box_corners
from ltc_cli.map.model import SemanticMap
from ltc_cli.map.store import save_map
from ltc_cli.validation import validate
from tests.sample_maps import add, big_map, hand_map

A, F = 6378137.0, 1 / 298.257223563
E2 = F * (2 - F)


@pytest.fixture(scope="module")
def map_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("x") / "hand.h5"
    save_map(hand_map(), path)
    return path


def wide_map(seed=1):
    """30 boxes of every orientation spread over 100 m x 100 m around the origin."""
    rng = np.random.default_rng(seed)
    m = SemanticMap.new(["chair", "table", "sofa"])
    m.created = "2026-01-01T00:00:00+00:00"
    corners = [(-50, -50), (50, -50), (50, 50), (-50, 50)]
    for i in range(30):
        xy = corners[i] if i < 4 else rng.uniform(-50, 50, 2)
        add(m, [xy[0], xy[1], 0.5], float(rng.uniform(-np.pi / 2, np.pi / 2)),
            rng.uniform(0.3, 3.0, 3), ["chair", "table", "sofa"][i % 3], float(rng.uniform(0.4, 0.95)))
    return m


# -- JSON --------------------------------------------------------------------------------------

def test_json_export_validates_and_holds_every_active_object():
    smap = hand_map()
    doc = ex.export_json(smap, "hand.h5")
    validate(doc, "export", "export.json")
    json.loads(ex.dumps(doc))  # strict JSON (no NaN)
    assert doc["classes"] == ["chair", "table", "tv"]
    assert [o["id"] for o in doc["objects"]] == [1, 2, 3, 4, 5]
    assert doc["map"]["sessions"][1]["sources"] == ["/data/lap2"] and doc["map"]["frames"] == 23
    o = doc["objects"][2]
    assert o["class"] == "table" and o["confidence"] == 0.9
    assert list(o["scores"]) == ["chair", "table", "tv", "other"]
    assert sum(o["scores"].values()) == pytest.approx(1.0)
    np.testing.assert_allclose(o["corners"], box_corners([0, 2, 0.4], -0.2, [1.6, 0.9, 0.8]), atol=1e-6)
    assert o["first_seen"] == {"session": 0, "frame": 1} and o["n_det"] == 3 and o["defined"] is True


def test_json_schema_rejects_a_broken_export():
    doc = ex.export_json(hand_map())
    doc["objects"][1]["corners"] = doc["objects"][1]["corners"][:7]
    with pytest.raises(Exception, match=r"out\.json: at objects\.1\.corners"):
        validate(doc, "export", "out.json")


# -- GeoJSON in local metres ---------------------------------------------------------------------

def check_polygons(doc, smap):
    """Every feature: a valid, closed, counter-clockwise footprint (shapely), one per active object."""
    rows = smap.active_rows()
    assert [f["id"] for f in doc["features"]] == (rows + 1).tolist()
    for f in doc["features"]:
        ring = f["geometry"]["coordinates"][0]
        assert len(ring) == 5 and ring[0] == ring[-1]  # closed (RFC 7946 3.1.6)
        poly = shape(f["geometry"])
        assert poly.is_valid and poly.exterior.is_ccw
        assert len(f["geometry"]["coordinates"]) == 1  # no holes
    return [shape(f["geometry"]) for f in doc["features"]]


def test_geojson_local_footprints_are_valid_ccw_with_the_right_area():
    smap = wide_map()
    doc = ex.export_geojson(smap)
    validate(doc, "geojson-export", "out.geojson")
    assert doc["type"] == "FeatureCollection" and doc["ltc:crs"] == "local-metres" and doc["ltc:origin"] is None
    polys = check_polygons(doc, smap)
    t = smap.objects
    for poly, f in zip(polys, doc["features"]):
        r = f["id"] - 1
        # Coordinates are rounded to 0.1 mm: the area is exact to well under a square centimetre.
        assert poly.area == pytest.approx(t.size[r, 0] * t.size[r, 1], abs=2e-4)
        assert poly.centroid.x == pytest.approx(t.center[r, 0], abs=1e-4)
        assert poly.centroid.y == pytest.approx(t.center[r, 1], abs=1e-4)
        p = f["properties"]
        assert p["z_min"] == pytest.approx(t.center[r, 2] - t.size[r, 2] / 2, abs=1e-6)
        assert p["z_max"] == pytest.approx(t.center[r, 2] + t.size[r, 2] / 2, abs=1e-6)
        assert p["height"] == pytest.approx(t.size[r, 2], abs=1e-6)
        assert p["class"] in ("chair", "table", "sofa") and 0 < p["confidence"] <= 1
    lo = np.min([p.bounds[:2] for p in polys], axis=0)
    hi = np.max([p.bounds[2:] for p in polys], axis=0)
    np.testing.assert_allclose(doc["bbox"], [*lo, *hi])


# -- geodesy -------------------------------------------------------------------------------------

def test_ecef_reference_points_and_round_trip():
    np.testing.assert_allclose(ex.geodetic_to_ecef(0, 0, 0), [A, 0, 0], atol=1e-6)
    np.testing.assert_allclose(ex.geodetic_to_ecef(90, 0, 0), [0, 0, A * (1 - F)], atol=1e-6)
    np.testing.assert_allclose(ex.geodetic_to_ecef(0, 90, 100), [0, A + 100, 0], atol=1e-6)
    rng = np.random.default_rng(0)
    lat, lon, h = rng.uniform(-89.99, 89.99, 500), rng.uniform(-180, 180, 500), rng.uniform(-100, 9000, 500)
    lat2, lon2, h2 = ex.ecef_to_geodetic(ex.geodetic_to_ecef(lat, lon, h))
    np.testing.assert_allclose(lat2, lat, atol=1e-10)
    np.testing.assert_allclose(lon2, lon, atol=1e-10)
    np.testing.assert_allclose(h2, h, atol=1e-5)
    pole = ex.ecef_to_geodetic([0.0, 0.0, A * (1 - F) + 5])
    assert pole[0] == pytest.approx(90.0) and pole[2] == pytest.approx(5.0, abs=1e-6)


def textbook_offsets(lon, lat, lon0, lat0):
    """Independent small-distance formula (not the ECEF path): east = N cos(phi_m) dlambda,
    north = M dphi, with the WGS84 meridian (M) and prime-vertical (N) radii of curvature at the mid
    latitude phi_m. Good to a few millimetres over 100 m."""
    phi_m = np.radians((np.asarray(lat) + lat0) / 2)
    w = np.sqrt(1 - E2 * np.sin(phi_m) ** 2)
    M, N = A * (1 - E2) / w ** 3, A / w
    return (N * np.cos(phi_m) * np.radians(np.asarray(lon) - lon0), M * np.radians(np.asarray(lat) - lat0))


def test_heading_convention():
    """heading = bearing of the map's +y axis, clockwise from north."""
    pts = np.array([[0.0, 10.0], [10.0, 0.0]])
    np.testing.assert_allclose(ex.map_xy_to_enu(pts, 0.0), [[0, 10], [10, 0]], atol=1e-12)  # +y north, +x east
    np.testing.assert_allclose(ex.map_xy_to_enu(pts, 90.0), [[10, 0], [0, -10]], atol=1e-12)  # +y east, +x south
    (lon_y, lat_y), (lon_x, lat_x) = ex.map_xy_to_lonlat(pts, (45.0, 7.0, 90.0))
    assert lon_y > 7.0 and lat_y == pytest.approx(45.0, abs=1e-8)  # +y went east
    assert lat_x < 45.0 and lon_x == pytest.approx(7.0, abs=1e-12)  # +x went south
    # 1 m north is 1 / M radians of latitude (M = 6367.4 km at 45 deg).
    _, lat1 = ex.map_xy_to_lonlat(np.array([0.0, 1.0]), (45.0, 7.0, 0.0))
    assert math.radians(lat1 - 45.0) * 6367381.8 == pytest.approx(1.0, abs=1e-5)


@pytest.mark.parametrize("origin", [(48.8566, 2.3522, 0.0), (36.7213, -4.4214, 37.5), (-33.9, 151.2, 250.0),
                                    (64.1, -21.9, 300.0)])
def test_geojson_wgs84_round_trips_within_1cm_over_100m(origin):
    smap = wide_map()
    doc = ex.export_geojson(smap, origin)
    validate(doc, "geojson-export", "out.geojson")
    assert doc["ltc:crs"] == ex.CRS_WGS84 and doc["ltc:origin"]["heading_deg"] == origin[2]
    check_polygons(doc, smap)  # in lon/lat the rings stay counter-clockwise
    t = smap.objects
    lat0, lon0, heading = origin
    h = math.radians(heading)
    worst_exact = worst_textbook = 0.0
    for f in doc["features"]:
        r = f["id"] - 1
        expect_xy = box_corners(t.center[r], t.yaw[r], t.size[r])[:4, :2]
        ring = np.array(f["geometry"]["coordinates"][0][:4])
        lon, lat = ring[:, 0], ring[:, 1]
        # Exact inverse: geodetic -> ECEF -> ENU, then east/north back into the map's x/y.
        enu = ex.geodetic_to_enu(lat, lon, 0.0, lat0, lon0)
        e, n = enu[:, 0], enu[:, 1]
        xy = np.c_[e * math.cos(h) - n * math.sin(h), e * math.sin(h) + n * math.cos(h)]
        worst_exact = max(worst_exact, float(np.abs(xy - expect_xy).max()))
        # Independent: the textbook radii-of-curvature formula, and the rotation written out anew.
        e2, n2 = textbook_offsets(lon, lat, lon0, lat0)
        x2 = e2 * math.cos(h) - n2 * math.sin(h)
        y2 = e2 * math.sin(h) + n2 * math.cos(h)
        worst_textbook = max(worst_textbook, float(np.abs(np.c_[x2, y2] - expect_xy).max()))
        # The box's x axis bearing: heading + 90 - yaw (mod 180).
        b = f["properties"]["x_axis_bearing_deg"]
        d = (b - (heading + 90 - math.degrees(t.yaw[r]))) % 180
        assert min(d, 180 - d) < 1e-5
    assert worst_exact < 0.001, worst_exact  # rounding to 1e-9 deg and the tangent plane: < 1 mm
    assert worst_textbook < 0.01, worst_textbook


# -- the command line ----------------------------------------------------------------------------

def test_cli_export_to_file_and_stdout(map_file, tmp_path):
    out = tmp_path / "map.geojson"
    r = CliRunner().invoke(cli, ["export", str(map_file), "--format", "geojson", "-o", str(out),
                                 "--origin", "36.7213,-4.4214,12"])
    assert r.exit_code == 0, r.output
    assert r.stdout == "" and "5 objects exported as geojson (WGS84 lon/lat)" in r.stderr
    doc = json.loads(out.read_text())
    validate(doc, "geojson-export", out)
    assert not list(tmp_path.glob(".*tmp*"))  # the atomic write left nothing behind
    r = CliRunner().invoke(cli, ["export", str(map_file), "--format", "json"])
    assert r.exit_code == 0
    validate(json.loads(r.stdout), "export", "stdout")
    assert r.stderr.strip() == f"{map_file}: 5 objects exported as json to stdout"
    r = CliRunner().invoke(cli, ["export", str(map_file), "--format", "geojson"])
    assert json.loads(r.stdout)["ltc:crs"] == "local-metres"


def test_cli_export_bad_arguments(map_file, tmp_path):
    def run(*a):
        return CliRunner().invoke(cli, ["export", str(map_file), *a])

    assert run("--format", "geojson", "--origin", "91,0").exit_code == 2
    assert run("--format", "geojson", "--origin", "north").exit_code == 2
    assert run("--format", "json", "--origin", "1,2").exit_code == 2
    assert run("--format", "xml").exit_code == 2
    bad = tmp_path / "no-such-dir" / "x.json"
    r = run("--format", "json", "-o", str(bad))
    assert r.exit_code == 1 and str(bad) in r.stderr and len(r.stderr.strip().splitlines()) == 1


def test_100k_export_time(tmp_path, capsys):
    smap = big_map(100_000)
    t0 = time.perf_counter()
    doc = ex.export_json(smap)
    t1 = time.perf_counter()
    text = ex.dumps(doc)
    t2 = time.perf_counter()
    n_json, mb_json = len(doc["objects"]), len(text) / 1e6
    del doc, text
    gdoc = ex.export_geojson(smap, (36.7213, -4.4214, 20.0))
    t3 = time.perf_counter()
    gtext = ex.dumps(gdoc)
    t4 = time.perf_counter()
    assert n_json == len(gdoc["features"]) == len(smap.active_rows())
    validate({**gdoc, "features": gdoc["features"][:200]}, "geojson-export")
    ring = gdoc["features"][123]["geometry"]["coordinates"][0]
    assert Polygon(ring).exterior.is_ccw
    with capsys.disabled():
        print(f"\n[export 100k] json: build {t1 - t0:.2f} s + text {t2 - t1:.2f} s ({mb_json:.0f} MB); "
              f"geojson WGS84: build {t3 - t2:.2f} s + text {t4 - t3:.2f} s ({len(gtext) / 1e6:.0f} MB)")

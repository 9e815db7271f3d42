"""The streamed exports (ltc_cli.map.export_stream, numbers formatted with numpy) are byte for byte
what ``json`` writes for the same maps: against the dict exports run through ``dumps``, against
digests of the exports written before streaming existed, and value by value against json.dumps."""

import hashlib
import json
import re

import numpy as np
import pytest
from click.testing import CliRunner

from ltc_cli.cli import cli
from ltc_cli.map import export as ex
from ltc_cli.map import json_text as jt
from ltc_cli.map.export_stream import export_chunks
from ltc_cli.map.model import REMOVED, SemanticMap
from ltc_cli.map.store import save_map
from tests.sample_maps import big_map, hand_map, house_map

ORIGINS = [None, (36.7213, -4.4214, 20.0), (-33.9, 151.2, 359.9)]


def reference(smap, fmt, origin):
    doc = ex.export_json(smap, "m.h5") if fmt == "json" else ex.export_geojson(smap, origin, "m.h5")
    return ex.dumps(doc).encode("utf-8")


def no_active():
    smap = hand_map()
    smap.objects.cols["status"][:] = REMOVED
    return smap


@pytest.mark.parametrize("make", [hand_map, lambda: house_map()[0], lambda: big_map(400, seed=3), no_active,
                                  lambda: SemanticMap.new(["a"])])
@pytest.mark.parametrize("fmt,origin", [("json", None)] + [("geojson", o) for o in ORIGINS])
@pytest.mark.parametrize("chunk", [1, 97, 4096])
def test_streamed_text_is_the_dict_export_text(make, fmt, origin, chunk):
    smap = make()
    assert b"".join(export_chunks(smap, fmt, origin, "m.h5", chunk=chunk)) == reference(smap, fmt, origin)


# sha256 and length of the exports of big_map(300, seed=7) written by ltc before streaming (9ca1c1a).
GOLDEN = {
    ("json", None): (283273, "7a8c01588056c76f12ceb58693e08ab91dbde345850a471e4cd802e1ecce87d9"),
    ("geojson", None): (259006, "c114b6e8c38d9c4900f82f1c6a2ca6ca803721c956e1c31030b9430d72bdab8a"),
    ("geojson", ORIGINS[1]): (281256, "71f9b455a7f3a7cd23e0fe2866ece3500b5e1d1ac3694f7134f7eaedee3957bc"),
}


@pytest.mark.parametrize("fmt,origin", list(GOLDEN))
def test_streamed_text_is_the_text_written_before(fmt, origin):
    text = b"".join(export_chunks(big_map(300, seed=7), fmt, origin, "big.h5"))
    if fmt == "json":  # sessions carry their cameras since the fiftieth round (none in this map), their
        # still frames since the fifty-fourth (none) and their frame range since the fifty-seventh (all)
        assert text.count(b'"cameras": []') == 1 and text.count(b'"frames_still": 0') == 1
        assert text.count(b'"frames": ""') == 1
        text = re.sub(rb',\s*"cameras": \[\]', b"", text)
        text = re.sub(rb',\s*"frames_still": 0', b"", text)
        text = re.sub(rb',\s*"frames": ""', b"", text)
    assert (len(text), hashlib.sha256(text).hexdigest()) == GOLDEN[(fmt, origin)]


def test_repeated_class_names_take_the_dict_path():
    smap = SemanticMap.new(["chair", "chair"])
    smap.objects.append(center=[0, 0, 0.5], yaw=0.0, size=[1, 1, 1], visible=np.ones(8, bool), defined=True,
                        scores=[0.5, 0.3, 0.2])
    assert b"".join(export_chunks(smap, "json")) == ex.dumps(ex.export_json(smap)).encode()


def as_json_list(values, kind):
    return "[" + ",".join(json.dumps(kind(v), allow_nan=False) for v in values) + "]"


@pytest.mark.parametrize("d", range(1, 10))
def test_decimals_are_json_floats(d):
    rng = np.random.default_rng(d)
    x = np.concatenate([
        rng.uniform(-1, 1, 3000), rng.uniform(-1e3, 1e3, 3000), rng.uniform(-2e6, 2e6, 500),
        10.0 ** rng.uniform(-12, 17, 2000) * rng.choice([-1, 1], 2000),  # tiny (1e-05 in json) and huge
        [0.0, -0.0, 1e-4, -1e-4, 9.9999e-5, 999999.999999, 1e6, -1e6, 0.5, 1.0, 123456.0, 2.0 ** 52],
    ]).round(d)
    got = jt.pack(jt.seq(jt.decimals(x, d)))
    assert got.decode() == as_json_list(x.tolist(), float)


def test_integers_and_booleans_are_json():
    rng = np.random.default_rng(0)
    v = np.concatenate([rng.integers(-10 ** 6, 10 ** 6, 1000), rng.integers(-2 ** 62, 2 ** 62, 200),
                        [0, 1, -1, 9, 10, 999, 1000, -1000, 2 ** 63 - 1, -2 ** 63, 2 ** 50, 2 ** 50 - 1]])
    assert jt.pack(jt.seq(jt.integers(v))).decode() == as_json_list(v.tolist(), int)
    b = rng.random(50) < 0.5
    assert jt.pack(jt.seq(jt.booleans(b))).decode() == json.dumps(b.tolist(), separators=(",", ":"))


def test_nested_lists_and_objects():
    x = np.array([[[1.5, -2.0], [0.25, 3.0]], [[-0.0, 7.125], [1e-05, 2.0]]])
    got = jt.pack(jt.cat(jt.seq(jt.seq(jt.decimals(x, 6))), jt.lit("|"), jt.seq(jt.decimals(x[:, 0], 6), ["a", "é"]),
                         jt.lit("\n")))
    want = "".join(json.dumps(x[i].tolist(), separators=(",", ":")) + "|"
                   + json.dumps(dict(zip(["a", "é"], x[i, 0].tolist())), separators=(",", ":"), ensure_ascii=False)
                   + "\n" for i in range(2))
    assert got.decode() == want


def test_cli_export_file_is_the_reference_text(tmp_path):
    smap = big_map(300, seed=7)
    path = tmp_path / "big.h5"
    save_map(smap, path)
    for fmt, extra in [("json", []), ("geojson", ["--origin", "36.7213,-4.4214,20"])]:
        out = tmp_path / f"big.{fmt}"
        r = CliRunner().invoke(cli, ["export", str(path), "--format", fmt, "-o", str(out), *extra])
        assert r.exit_code == 0, r.output
        origin = None if fmt == "json" else (36.7213, -4.4214, 20.0)
        doc = ex.export_json(smap, path) if fmt == "json" else ex.export_geojson(smap, origin, path)
        assert out.read_bytes() == ex.dumps(doc).encode()
        assert f"{len(smap.active_rows())} objects exported as {fmt}" in r.stderr
        r = CliRunner().invoke(cli, ["export", str(path), "--format", fmt, *extra])
        assert r.stdout_bytes == out.read_bytes()
    assert not list(tmp_path.glob(".*tmp*"))


def test_a_failing_stream_leaves_no_file(tmp_path):
    from ltc_cli.map.export_stream import write_export

    out = tmp_path / "x.json"
    out.write_text("old")

    def chunks():
        yield b"{"
        raise ValueError("Out of range float values are not JSON compliant")

    with pytest.raises(ValueError):
        write_export(out, chunks())
    assert out.read_text() == "old" and not list(tmp_path.glob(".*tmp*"))

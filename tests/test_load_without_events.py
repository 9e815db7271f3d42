"""load_map(path, events=False): everything but the event log, with every check that needs no
event's contents; info, query (without --removed), export and render use it."""

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from ltc_cli.cli import cli
from ltc_cli.errors import MapFormatError
from ltc_cli.map.query import removal_events
from ltc_cli.map.store import load_map, map_image, save_map
from tests.sample_maps import hand_map


@pytest.fixture
def map_file(tmp_path):
    path = tmp_path / "hand.h5"
    save_map(hand_map(), path)
    return path


def test_everything_but_the_events(map_file):
    full, lean = load_map(map_file), load_map(map_file, events=False)
    assert len(full.events) == 12 and full.n_events == 12 and full.unread_events is None
    assert lean.events == [] and lean.n_events == 12 and lean.unread_events == 12
    assert (lean.classes, lean.sessions, lean.frame_keys, lean.created) == \
        (full.classes, full.sessions, full.frame_keys, full.created)
    np.testing.assert_array_equal(lean.up_rotation, full.up_rotation)
    for name, col in full.objects.columns().items():
        np.testing.assert_array_equal(lean.objects.columns()[name], col)
    # Nothing may read removals from, or save, a map whose log stayed on disk.
    with pytest.raises(RuntimeError, match="without its event log"):
        removal_events(lean)
    with pytest.raises(RuntimeError, match="without its event log"):
        map_image(lean)


def test_only_the_removals(map_file):
    """events=("removed",): the log's removal events exactly as the whole log holds them, in
    order; the count of all; such a map neither saves nor gives events of another kind."""
    full, lean = load_map(map_file), load_map(map_file, events=("removed",))
    assert lean.events == [e for e in full.events if e.kind == "removed"] and len(lean.events) >= 1
    assert lean.n_events == 12 and lean.event_kinds == ("removed",)
    assert removal_events(lean) == removal_events(full)
    with pytest.raises(RuntimeError, match="without its event log"):
        map_image(lean)
    with pytest.raises(RuntimeError, match="without its event log"):
        lean.require_events("created")


def _replace(f, name, data):
    del f[name]
    f[name] = data


# Damage to the event log that shows without reading its contents: found either way, in the same words.
DAMAGES = {
    "cut": (lambda f: _replace(f, "events/kind", f["events/kind"][:3]),
            "the events columns have different lengths (events/kind has 3, the others 12 rows)"),
    "floats": (lambda f: _replace(f, "events/frame", np.asarray(f["events/frame"], float)),
               "events/frame holds decimal numbers, not integers"),
    "numbers-for-text": (lambda f: _replace(f, "events/detail", np.zeros(12, np.int64)),
                         "events/detail holds integers, not text"),
    "2-d": (lambda f: _replace(f, "events/object_id", np.zeros((12, 2), np.int64)),
            "events/object_id has shape (12, 2); expected one value per row"),
    "missing": (lambda f: f.__delitem__("events/other_id"), "the dataset events/other_id is missing"),
}


@pytest.mark.parametrize("damage", list(DAMAGES))
def test_damaged_event_log_is_refused_without_reading_it(map_file, damage):
    change, expected = DAMAGES[damage]
    with h5py.File(map_file, "a") as f:
        change(f)
    for events in (True, False, ("removed",)):
        with pytest.raises(MapFormatError, match="damaged ltc map") as err:
            load_map(map_file, events=events)
        assert expected in str(err.value)


def test_variable_length_text_events(map_file):
    # Maps written by other tools may hold variable-length strings: counted all the same.
    with h5py.File(map_file, "a") as f:
        kinds = [k.decode() for k in f["events/kind"][()]]
        del f["events/kind"]
        f.create_dataset("events/kind", data=kinds, dtype=h5py.string_dtype())
    assert load_map(map_file, events=False).n_events == 12
    assert [e.kind for e in load_map(map_file).events] == kinds
    assert [e.kind for e in load_map(map_file, events=("removed",)).events] == [k for k in kinds if k == "removed"]


def test_commands_with_and_without_the_log(map_file, tmp_path):
    def run(*args):
        r = CliRunner().invoke(cli, [*args])
        assert r.exit_code == 0, r.output
        return r.stdout

    assert "5 objects" in run("info", str(map_file)) and "12 events logged" in run("info", str(map_file))
    assert '"id": 5' in run("query", str(map_file), "--id", "5", "--format", "json")
    removed = run("query", str(map_file), "--removed", "--format", "json")
    assert "other 0.520 > chair 0.400" in removed and '"frame_key": "lap2/000012"' in removed
    run("render", str(map_file), "-o", str(tmp_path / "m.png"), "--changes", "--since", "0")
    run("render", str(map_file), "-o", str(tmp_path / "m.png"))

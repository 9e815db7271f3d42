"""The manifest of ``ltc ingest-many``: recordings -> maps (schemas/manifest.schema.json).

Everything that concerns the manifest itself (its schema, each map's settings and calibration, the
same map named twice) is checked before any map is touched, and refused with one line naming the
manifest; a recording that cannot be read is a failure of that recording only, found when its
turn comes.
"""

from __future__ import annotations

import datetime as dt
import os
from dataclasses import dataclass
from pathlib import Path

from ltc_cli.config import load_config, read_yaml
from ltc_cli.errors import ConfigError
from ltc_cli.recordings.open import frame_range
from ltc_cli.tools.calibration_file import load_calibration
from ltc_cli.validation import validate

FORMAT = "ltc-manifest/1"


@dataclass
class RecordingEntry:
    path: Path
    time: dt.datetime | None
    reader: str | None
    options: dict | None = None  # reader options (ltc ingest -r)
    frames: slice | None = None  # ltc ingest --frames


@dataclass
class MapJob:
    """One map and its recordings, in the order they are ingested."""

    name: str
    path: Path
    config: dict
    calibration: dict | None
    recordings: list[RecordingEntry]


def _isoformat(node):
    """YAML reads an unquoted 2024-05-01 or 2024-05-01T09:00:00Z as a date / datetime: back to text,
    so that the schema sees what the user wrote."""
    if isinstance(node, dict):
        return {k: _isoformat(v) for k, v in node.items()}
    if isinstance(node, list):
        return [_isoformat(v) for v in node]
    if isinstance(node, (dt.date, dt.datetime)):
        return node.isoformat()
    return node


def parse_time(text: str) -> dt.datetime:
    """An ISO 8601 date or date-time as an aware datetime (no zone: UTC)."""
    t = dt.datetime.fromisoformat(text.replace(" ", "T", 1))
    return t if t.tzinfo is not None else t.replace(tzinfo=dt.timezone.utc)


def _recording(item, base: Path, where: str, manifest: Path) -> RecordingEntry:
    if isinstance(item, str):
        item = {"path": item}
    try:
        frames = frame_range(item["frames"]) if "frames" in item else None
    except ConfigError as exc:
        raise ConfigError(f"at {where}: {exc.message}", manifest) from None
    return RecordingEntry(base / item["path"], parse_time(item["time"]) if "time" in item else None,
                          item.get("format"), item.get("options"), frames)


def _in_time_order(recs: list[RecordingEntry], where: str, manifest: Path) -> list[RecordingEntry]:
    timed = [r.time is not None for r in recs]
    if all(timed):
        return sorted(recs, key=lambda r: r.time)  # stable: equal times keep the listed order
    if any(timed):
        raise ConfigError(f"at {where}: give every recording a time, or none (then the listed order is kept)",
                          manifest)
    return recs


def load_manifest(path) -> list[MapJob]:
    """The maps of the manifest at ``path``, each with its settings and recordings in time order."""
    manifest = Path(path)
    doc = read_yaml(manifest, "manifest")
    doc = _isoformat(doc)
    validate(doc, "manifest", manifest)
    base = manifest.parent
    jobs, seen = [], {}
    for i, m in enumerate(doc["maps"]):
        where = f"maps.{i}"
        map_path = base / m["map"]
        real = os.path.realpath(map_path)
        if real in seen:
            raise ConfigError(f"at {where}: {m['map']} is the map of maps.{seen[real]} too (one writer per map: "
                              f"list its recordings once)", manifest)
        seen[real] = i
        config_file = m.get("config", doc.get("config"))
        config = load_config(base / config_file if config_file else None, [*doc.get("set", []), *m.get("set", [])])
        cal_file = m.get("calibration", doc.get("calibration"))
        calibration = load_calibration(base / cal_file) if cal_file else None
        recs = _in_time_order([_recording(r, base, f"{where}.recordings.{k}", manifest)
                               for k, r in enumerate(m["recordings"])], f"{where}.recordings", manifest)
        jobs.append(MapJob(m.get("name") or map_path.name, map_path, config, calibration, recs))
    return jobs

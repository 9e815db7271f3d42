"""The one configuration of ltc: defaults.yaml, then a user file, then ``--set key=value``."""

from __future__ import annotations

import copy
from importlib import resources
from pathlib import Path

import yaml

from ltc_cli.errors import ConfigError

# Keys whose value is a free-form mapping (plugin options) or may be null.
_FREE = {("detector", "options"), ("modeling", "class_depth"), ("maintenance", "v_other_per_class")}
_NULLABLE = {("integration", "max_weight"), ("map", "classes"), ("maintenance", "min_visible_fraction"), ("association", "containment"), ("association", "containment_other_class"), ("modeling", "edge_jump")}


def defaults() -> dict:
    text = resources.files("ltc_cli").joinpath("defaults.yaml").read_text()
    return yaml.safe_load(text)


def _check_and_merge(base: dict, update: dict, where: str, trail: tuple = (), replace: bool = True) -> None:
    if not isinstance(update, dict):
        raise ConfigError(f"{'.'.join(trail) or 'top level'} must be a mapping", where)
    for key, value in update.items():
        path = trail + (key,)
        dotted = ".".join(path)
        if key not in base:
            raise ConfigError(f"unknown setting {dotted!r}", where)
        current = base[key]
        if path in _FREE:
            if not isinstance(value, dict):
                raise ConfigError(f"{dotted} must be a mapping", where)
            # A file replaces a mapping setting whole (so {} empties it); each --set adds one key.
            base[key] = dict(value) if replace else {**current, **value}
        elif isinstance(current, dict):
            _check_and_merge(current, value, where, path, replace)
        else:
            base[key] = _coerce(current, value, path, where)


def _coerce(current, value, path, where):
    dotted = ".".join(path)
    if value is None:
        if path in _NULLABLE:
            return None
        raise ConfigError(f"{dotted} cannot be null", where)
    if path in _NULLABLE and current is None:
        return value
    if isinstance(current, bool):
        if not isinstance(value, bool):
            raise ConfigError(f"{dotted} must be true or false, got {value!r}", where)
        return value
    if isinstance(current, (int, float)) and not isinstance(current, bool):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{dotted} must be a number, got {value!r}", where)
        if isinstance(current, int) and not isinstance(current, bool) and float(value).is_integer():
            return int(value)
        return float(value)
    if isinstance(current, str):
        if not isinstance(value, str):
            raise ConfigError(f"{dotted} must be a string, got {value!r}", where)
        return value
    if isinstance(current, list) and not isinstance(value, list):
        raise ConfigError(f"{dotted} must be a list", where)
    return value


def parse_set(item: str) -> dict:
    """``a.b=value`` (value read as YAML) -> {"a": {"b": value}}."""
    if "=" not in item:
        raise ConfigError(f"--set expects key=value, got {item!r}")
    key, raw = item.split("=", 1)
    key = key.strip()
    if not key:
        raise ConfigError(f"--set expects key=value, got {item!r}")
    try:
        value = yaml.safe_load(raw) if raw.strip() else ""
    except yaml.YAMLError:
        value = raw
    out: dict = {}
    node = out
    parts = key.split(".")
    for part in parts[:-1]:
        node = node.setdefault(part, {})
    node[parts[-1]] = value
    return out


def load_config(path=None, sets: list[str] = ()) -> dict:
    """Defaults, overridden by a YAML file and then by ``--set`` items; unknown keys are errors."""
    cfg = defaults()
    if path is not None:
        p = Path(path)
        try:
            data = yaml.safe_load(p.read_text())
        except OSError as exc:
            raise ConfigError(f"cannot read config ({exc.strerror})", p) from None
        except yaml.YAMLError as exc:
            raise ConfigError(f"not valid YAML ({str(exc).splitlines()[0]})", p) from None
        if data is not None:
            _check_and_merge(cfg, data, str(p))
    for item in sets:
        _check_and_merge(cfg, parse_set(item), f"--set {item}", replace=False)
    _validate(cfg)
    return cfg


def _validate(cfg: dict) -> None:
    m = cfg["modeling"]
    if not 0 <= m["min_depth"] < m["max_depth"]:
        raise ConfigError("modeling.min_depth must be >= 0 and below modeling.max_depth")
    if m["clustering"] not in ("grid", "voxel", "dbscan"):
        raise ConfigError("modeling.clustering must be grid, voxel or dbscan")
    for key in ("eps", "min_extent", "max_points", "min_samples", "max_detections"):
        if m[key] <= 0:
            raise ConfigError(f"modeling.{key} must be positive")
    if not isinstance(m["max_detections"], int):
        raise ConfigError("modeling.max_detections must be a whole number")
    v = cfg["maintenance"]["v_other"]
    if not 0 < v < 1:
        raise ConfigError("maintenance.v_other must be between 0 and 1")
    for name, vc in cfg["maintenance"]["v_other_per_class"].items():
        if isinstance(vc, bool) or not isinstance(vc, (int, float)) or not 0 < vc < 1:
            raise ConfigError(f"maintenance.v_other_per_class.{name} must be between 0 and 1")
    mw = cfg["integration"]["max_weight"]
    if mw is not None and mw < 1:
        raise ConfigError("integration.max_weight must be >= 1 or null")
    if cfg["maintenance"]["ray_step"] < 1:
        raise ConfigError("maintenance.ray_step must be >= 1")


def copy_config(cfg: dict) -> dict:
    return copy.deepcopy(cfg)

"""The one configuration of ltc: defaults.yaml, then a user file, then ``--set key=value``.

The merged settings are checked against ``config.schema.json`` (every key, its type and range), so
an unknown key, a wrong type, or a value out of range (negative, NaN, a zero cell size) is one
:class:`ConfigError` line naming the key and where its value came from, before any work starts.

Settings are one nested dict, typed section by section by :class:`ltc_cli.settings.Settings` and read
as ``cfg["section"]["key"]``. Every function here returns a
new one that shares nothing with its inputs, so a caller's dict is never written into: ingest builds
its own effective copy (:func:`settings_from`) rather than editing the one it was given.

Merging: a section of fixed keys (``modeling``) is merged key by key. A free mapping (per-class
tables such as ``modeling.class_depth``, the detector's ``options``) is replaced whole by a file, so
``{}`` in a file empties it, while each ``--set`` adds or replaces one key of it (``--set
modeling.class_depth={}`` empties it too: adding nothing would leave a user's "off" silently on),
changes one field of an entry (``--set modeling.top_under.sink.height=0.85``), or, with null,
takes an entry out (``--set modeling.top_under.sink=null``) where null is no value of the table.
"""

from __future__ import annotations

import copy
import difflib
import json
import math
from functools import lru_cache
from importlib import resources
from pathlib import Path

import yaml

from ltc_cli.errors import ConfigError
from ltc_cli.settings import Settings

SCHEMA_FILE = "config.schema.json"
# Keywords whose failure is described from the schema ("must be a number >= 0, got -3").
_SHAPE_KEYWORDS = {"type", "enum", "minimum", "maximum", "exclusiveMinimum", "exclusiveMaximum"}


def defaults() -> Settings:
    text = resources.files("ltc_cli").joinpath("defaults.yaml").read_text()
    # ltc's own file, always valid: libyaml's safe loader (same constructor, C parser) reads it
    # in a tenth of the time; users' files keep safe_load and its error marks.
    return yaml.load(text, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))  # noqa: S506 - a safe loader


@lru_cache(maxsize=None)
def schema() -> dict:
    """The settings schema (draft 2020-12), shipped beside defaults.yaml."""
    return json.loads(resources.files("ltc_cli").joinpath(SCHEMA_FILE).read_text())


def _is_finite_number(checker, value) -> bool:
    # jsonschema counts NaN and inf as numbers, and NaN passes every ``minimum`` (comparisons with
    # NaN are false), so a NaN threshold would slip through: in ltc's settings a number is finite.
    return (isinstance(value, (int, float)) and not isinstance(value, bool)
            and math.isfinite(value))


@lru_cache(maxsize=None)
def _validator_class():
    # jsonschema is imported here, not at the top: it costs ~0.06 s CPU, and `ltc --help`, `info`
    # and `query` import this module without ever validating settings.
    import jsonschema

    return jsonschema.validators.extend(
        jsonschema.Draft202012Validator,
        type_checker=jsonschema.Draft202012Validator.TYPE_CHECKER.redefine("number", _is_finite_number),
    )


# -- walking the schema ---------------------------------------------------------------------------

def _resolve(node: dict) -> dict:
    """``node`` with a local ``$ref`` (``#/$defs/NAME``) replaced by its target (sibling keys win)."""
    while "$ref" in node:
        target = schema()["$defs"][node["$ref"].rsplit("/", 1)[-1]]
        node = {**target, **{k: v for k, v in node.items() if k != "$ref"}}
    return node


def _child(node: dict | None, key) -> dict | None:
    """The schema of ``key`` inside ``node``: a fixed key, a free mapping's value, or a list item."""
    if node is None:
        return None
    if isinstance(key, int):
        items = node.get("items")
        return _resolve(items) if isinstance(items, dict) else None
    if key in node.get("properties", {}):
        return _resolve(node["properties"][key])
    extra = node.get("additionalProperties")
    return _resolve(extra) if isinstance(extra, dict) else None


def _node_at(path) -> dict | None:
    node = _resolve(schema())
    for key in path:
        node = _child(node, key)
    return node


def _dotted(path) -> str:
    out = ""
    for key in path:
        out += f"[{key}]" if isinstance(key, int) else (f".{key}" if out else str(key))
    return out or "(top level)"


# -- merging ----------------------------------------------------------------------------------------

def _merge(base: dict, update: dict, node: dict | None, origin: str, replace: bool, trail: tuple,
           origins: dict) -> None:
    """Merge ``update`` into ``base`` in place; ``origins`` records where each key's value came from.

    Unknown keys and values of the wrong shape are copied as they are: validation names them."""
    for key, value in update.items():
        path = trail + (key,)
        origins[path] = origin
        sub = _child(node, key) if isinstance(key, str) else None
        current = base.get(key)
        if value is None and not replace and _free(node) and not _takes_null(sub):
            base.pop(key, None)  # --set TABLE.KEY=null takes the key out of a free mapping
            continue
        if sub is not None and isinstance(value, dict) and isinstance(current, dict):
            # A section of fixed keys merges key by key; so does a free mapping given by --set,
            # into its entries too (``{}`` empties it): a bound's height alone can be changed.
            if "properties" in sub or (not replace and value):
                _merge(current, value, sub, origin, replace, path, origins)
                continue
        base[key] = copy.deepcopy(value)


def _free(node: dict | None) -> bool:
    """Whether ``node`` is a free mapping (per-class table): its keys are not fixed by the schema."""
    return node is not None and "properties" not in node and isinstance(node.get("additionalProperties"), dict)


def _takes_null(node: dict | None) -> bool:
    """Whether a value of schema ``node`` may be null (then null is a value, not a removal)."""
    if node is None:
        return True
    kinds = node.get("type")
    return kinds == "null" or (isinstance(kinds, list) and "null" in kinds) or \
        any(_takes_null(_resolve(n)) for n in node.get("anyOf", []) + node.get("oneOf", []))


def _origin_of(path: tuple, origins: dict):
    for n in range(len(path), 0, -1):
        if path[:n] in origins:
            return origins[path[:n]]
    return None


# -- validation -------------------------------------------------------------------------------------

def _number(v) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


def _expected(node: dict, value) -> str:
    """What ``node`` accepts, in words: 'a number between 0 and 1', 'an integer >= 1 or null'."""
    if "enum" in node:
        names = [str(v) for v in node["enum"]]
        return "one of " + (", ".join(names[:-1]) + " or " + names[-1] if len(names) > 1 else names[0])
    types = node.get("type", [])
    types = [types] if isinstance(types, str) else list(types)
    words = []
    for t in types:
        if t == "number":
            bad = isinstance(value, float) and not math.isfinite(value)
            words.append("a finite number" if bad else "a number")
        elif t != "null":
            words.append({"integer": "an integer", "boolean": "true or false", "object": "a mapping",
                          "array": "a list", "string": "a non-empty string" if node.get("minLength")
                          else "a string"}.get(t, t))
    text = " or ".join(words)
    lo = (">=", node["minimum"]) if "minimum" in node else (">", node.get("exclusiveMinimum"))
    hi = ("<=", node["maximum"]) if "maximum" in node else ("<", node.get("exclusiveMaximum"))
    if lo[1] is not None and hi[1] is not None:
        strict = " strictly" if lo[0] == ">" and hi[0] == "<" else ""
        text += f"{strict} between {_number(lo[1])} and {_number(hi[1])}"
    elif lo[1] is not None:
        text += f" {lo[0]} {_number(lo[1])}"
    elif hi[1] is not None:
        text += f" {hi[0]} {_number(hi[1])}"
    return text + (" or null" if "null" in types else "")


def _describe(error) -> tuple[tuple, str]:
    """(the key's path, one line) for a validation error."""
    path = tuple(error.absolute_path)
    node = _node_at(path) or {}
    if error.validator == "additionalProperties":
        known = list(node.get("properties", {}))
        extra = sorted((k for k in error.instance if k not in known), key=str)[0]
        hint = difflib.get_close_matches(str(extra), known, n=1)
        path += (extra,)
        dotted = _dotted(path)
        return path, f"unknown setting {dotted!r}" + (f" (did you mean {_dotted(path[:-1] + (hint[0],))}?)"
                                                        if hint else "")
    if error.validator == "required":
        missing = [k for k in node.get("required", []) if k not in error.instance][0]
        path += (missing,)
        return path, f"setting {_dotted(path)} is missing"
    if error.validator in _SHAPE_KEYWORDS:
        return path, f"setting {_dotted(path)}: must be {_expected(node, error.instance)}, got {error.instance!r}"
    return path, f"setting {_dotted(path)}: {error.message}"


def _coerce(value, node: dict | None):
    """Numbers as the schema types them: 10.0 for an integer setting is 10, 1 for a number is 1.0."""
    if node is None:
        return value
    if isinstance(value, dict):
        return {k: _coerce(v, _child(node, k)) for k, v in value.items()}
    if isinstance(value, list):
        return [_coerce(v, _child(node, i)) for i, v in enumerate(value)]
    types = node.get("type", [])
    types = [types] if isinstance(types, str) else types
    if "integer" in types and isinstance(value, float):
        return int(value)
    if "number" in types and "integer" not in types and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    return value


def validate_config(cfg: dict, origins: dict | None = None) -> Settings:
    """A checked copy of ``cfg`` (numbers typed as the schema says); ConfigError naming the first bad
    key, and the file or ``--set`` item its value came from when ``origins`` says."""
    origins = origins or {}
    from jsonschema.exceptions import best_match

    error = best_match(_validator_class()(schema()).iter_errors(cfg))
    if error is not None:
        path, line = _describe(error)
        raise ConfigError(line, _origin_of(path, origins))
    m = cfg["modeling"]
    if m["min_depth"] >= m["max_depth"]:
        path = ("modeling", "min_depth")
        raise ConfigError(f"setting modeling.min_depth: must be below modeling.max_depth ({_number(m['max_depth'])}), "
                          f"got {m['min_depth']!r}",
                          _origin_of(path, origins) or _origin_of(("modeling", "max_depth"), origins))
    return _coerce(copy.deepcopy(cfg), _resolve(schema()))


# -- building the settings --------------------------------------------------------------------------

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


def read_yaml(path, what: str):
    """The YAML document in ``path`` (safe_load); ConfigError naming the file when it cannot be
    read or parsed. ``what`` names the document in the message ("config", "calibration")."""
    p = Path(path)
    try:
        return yaml.safe_load(p.read_text())
    except OSError as exc:
        raise ConfigError(f"cannot read {what} ({exc.strerror})", p) from None
    except yaml.YAMLError as exc:
        raise ConfigError(f"{what} is not valid YAML ({str(exc).splitlines()[0]})", p) from None


def _read_file(path) -> dict:
    p = Path(path)
    data = read_yaml(p, "config")
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError("the settings must be a mapping of sections (modeling:, association:, ...)", p)
    return data


def load_config(path=None, sets: list[str] = ()) -> Settings:
    """Defaults, overridden by a YAML file and then by ``--set`` items, checked by the schema."""
    cfg = defaults()
    root = _resolve(schema())
    origins: dict = {}
    if path is not None:
        _merge(cfg, _read_file(path), root, str(path), True, (), origins)
    for item in sets:
        _merge(cfg, parse_set(item), root, f"--set {item}", False, (), origins)
    return validate_config(cfg, origins)


def settings_from(config: dict, *overrides: dict) -> Settings:
    """A checked copy of ``config`` with each partial mapping of ``overrides`` merged in as a file
    would be (a calibration's v_Other, say); ``config`` itself is left as it was."""
    cfg = copy.deepcopy(config)
    root = _resolve(schema())
    for update in overrides:
        _merge(cfg, update, root, "", True, (), {})
    return validate_config(cfg)

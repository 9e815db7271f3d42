"""Validation of the JSON / YAML documents ltc reads, and of plugin options, against JSON Schemas
(draft 2020-12).

Numbers must be finite: ``json.loads`` accepts ``NaN`` and ``Infinity`` and YAML has ``.nan``, and
since NaN fails no comparison, ``"minimum": 0`` alone would let it through. Tuples count as arrays
(options given from Python).
"""

from __future__ import annotations

import json
import math
from functools import lru_cache
from importlib import resources

import jsonschema

from ltc_cli.errors import ConfigError, SchemaError

_BASE = jsonschema.Draft202012Validator
_TYPES = _BASE.TYPE_CHECKER.redefine_many(
    {
        "number": lambda checker, x: _BASE.TYPE_CHECKER.is_type(x, "number") and math.isfinite(x),
        "integer": lambda checker, x: _BASE.TYPE_CHECKER.is_type(x, "integer") and math.isfinite(x),
        "array": lambda checker, x: isinstance(x, (list, tuple)),
    }
)
#: Draft 2020-12 with finite numbers only.
FiniteValidator = jsonschema.validators.extend(_BASE, type_checker=_TYPES)


@lru_cache(maxsize=None)
def load_schema(name: str) -> dict:
    """The schema ``schemas/<name>.schema.json``."""
    text = resources.files("ltc_cli.schemas").joinpath(f"{name}.schema.json").read_text()
    return json.loads(text)


def _message(error) -> str:
    if error.validator == "type" and isinstance(error.instance, float) and not math.isfinite(error.instance):
        return f"{error.instance} is not a finite number"
    return error.message


def _where(error) -> str:
    parts = [str(p) for p in error.absolute_path]
    return ".".join(parts) if parts else "(top level)"


@lru_cache(maxsize=None)
def _validator(name: str):
    return FiniteValidator(load_schema(name))


def validate(document, name: str, path=None) -> None:
    """Raise SchemaError naming the file and the path inside it of the first problem."""
    validator = _validator(name)  # built once per schema: the recorded detector checks every frame's file
    if validator.is_valid(document):  # stops at the first error; best_match below walks them all
        return
    error = jsonschema.exceptions.best_match(validator.iter_errors(document))
    if error is not None:
        raise SchemaError(f"at {_where(error)}: {_message(error)}", path)


@lru_cache(maxsize=None)
def _options_validator(schema_json: str):
    schema = json.loads(schema_json)
    FiniteValidator.check_schema(schema)  # a plugin's own schema must be valid (its author's bug)
    return FiniteValidator(schema)


def _option_message(error, schema: dict, options: dict) -> str:
    """One line naming the option of a jsonschema error of an options mapping."""
    path = list(error.absolute_path)
    props = schema.get("properties", {})
    if not path and error.validator == "additionalProperties":
        unknown = sorted(set(error.instance) - set(props))
        known = f"known: {', '.join(props)}" if props else "it takes no options"
        return f"unknown option(s) {', '.join(map(repr, unknown))} ({known})"
    if not path and error.validator == "required":
        missing = next(k for k in error.validator_value if k not in error.instance)
        about = props.get(missing, {}).get("description")
        return f"option {missing!r} is required" + (f": {about}" if about else "")
    if not path:
        return f"options {error.message}"
    prop = props.get(path[0], {})
    if "description" in prop and ("anyOf" in prop or "oneOf" in prop):
        # jsonschema's words for a failed alternative ("is not valid under any of the given
        # schemas") do not say what was wanted; the option's description does.
        return f"option {path[0]!r} must be {prop['description']}, got {options[path[0]]!r}"
    inner = ".".join(str(p) for p in path[1:])
    return f"option {path[0]!r}{' at ' + inner if inner else ''}: {_message(error)}"


def check_options(options, schema: dict, owner: str, error: type = ConfigError) -> dict:
    """A plugin's options checked against its schema, with the schema's defaults filled in.

    ``options`` is a mapping (None means {}); every property of ``schema`` that has a ``default``
    and is not given gets it. An unknown option, a missing required one or a bad value raises
    ``error`` with one line: ``"<owner>: option 'key' ..."``.
    """
    options = {} if options is None else options
    if not isinstance(options, dict):
        raise error(f"{owner}: options must be a mapping of option names to values, got {options!r}")
    validator = _options_validator(json.dumps(schema, sort_keys=True))
    found = jsonschema.exceptions.best_match(validator.iter_errors(options))
    if found is not None:
        raise error(f"{owner}: {_option_message(found, schema, options)}")
    defaults = {k: p["default"] for k, p in schema.get("properties", {}).items() if "default" in p}
    return {**defaults, **options}

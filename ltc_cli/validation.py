"""Validation of the JSON / YAML documents ltc reads against the JSON Schemas in schemas/."""

from __future__ import annotations

import json
from functools import lru_cache
from importlib import resources

import jsonschema

from ltc_cli.errors import SchemaError


@lru_cache(maxsize=None)
def load_schema(name: str) -> dict:
    """The schema ``schemas/<name>.schema.json``."""
    text = resources.files("ltc_cli.schemas").joinpath(f"{name}.schema.json").read_text()
    return json.loads(text)


def _where(error) -> str:
    parts = [str(p) for p in error.absolute_path]
    return ".".join(parts) if parts else "(top level)"


def validate(document, name: str, path=None) -> None:
    """Raise SchemaError naming the file and the path inside it of the first problem."""
    validator = jsonschema.Draft202012Validator(load_schema(name))
    error = jsonschema.exceptions.best_match(validator.iter_errors(document))
    if error is not None:
        raise SchemaError(f"at {_where(error)}: {error.message}", path)

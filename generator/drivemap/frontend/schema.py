"""JSON Schema validation with errors mapped back to line/column.

:func:`validate` checks a loaded document against a schema file: the map schema by default, or any
other schema drivemap ships (the gateway's configuration, ``data/gateway.schema.json``).
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from functools import lru_cache
from pathlib import Path
from typing import Any

import jsonschema
from jsonschema.exceptions import ValidationError

from drivemap.diagnostics import Diagnostic
from drivemap.frontend.load import Document, PathT

#: The schema shipped with the package. In the repository this is a link to the one source of
#: truth, ``schemas/drivemap.schema.json``; a wheel carries the file itself.
SCHEMA_PATH = Path(__file__).resolve().parent.parent / "data" / "drivemap.schema.json"


@lru_cache(maxsize=8)
def load_schema(path: Path = SCHEMA_PATH) -> dict[str, Any]:
    """The JSON Schema in ``path`` (cached)."""
    with open(path, encoding="utf-8") as handle:
        loaded: dict[str, Any] = json.load(handle)
    return loaded


def schema() -> dict[str, Any]:
    """The map schema."""
    return load_schema(SCHEMA_PATH)


@lru_cache(maxsize=8)
def validator(path: Path = SCHEMA_PATH) -> jsonschema.Draft202012Validator:
    """A validator for the schema in ``path`` (default: the map schema), cached."""
    made: jsonschema.Draft202012Validator = _StrictIntegers(load_schema(path))
    return made


def _is_integer(_checker: Any, instance: Any) -> bool:
    """``integer`` means a YAML integer: JSON Schema would also accept ``1.0``, which the model
    and the generated code must never see where an int is promised."""
    return isinstance(instance, int) and not isinstance(instance, bool)


_StrictIntegers = jsonschema.validators.extend(  # type: ignore[no-untyped-call]
    jsonschema.Draft202012Validator,
    type_checker=jsonschema.Draft202012Validator.TYPE_CHECKER.redefine("integer", _is_integer),
)


def dotted(path: Iterable[str | int]) -> str:
    """``('registers', 3, 'address')`` -> ``registers[3].address``."""
    text = ""
    for part in path:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else str(part))
    return text or "(top level)"


def short(value: Any, limit: int = 50) -> str:
    text = repr(value) if not isinstance(value, (dict, list)) else type(value).__name__
    return text if len(text) <= limit else text[: limit - 3] + "..."


_TYPE_NAMES = {"object": "a mapping", "array": "a list", "string": "a string", "integer": "an integer",
               "number": "a number", "boolean": "true/false", "null": "null"}


def _leaf(error: ValidationError) -> ValidationError:
    """For oneOf/anyOf failures, the most specific sub-error (the deepest path)."""
    while error.context:
        candidates = [e for e in error.context if e.validator not in ("type", "const")] or list(error.context)
        error = max(candidates, key=lambda e: (len(e.absolute_path), e.validator != "type"))
    return error


def _message(error: ValidationError) -> tuple[PathT, str, bool]:
    """(path, message, point-at-key?) for one error."""
    path: PathT = tuple(error.absolute_path)
    kind: Any = error.validator
    inst: Any = error.instance
    sub: Any = error.schema if isinstance(error.schema, dict) else {}
    value: Any = error.validator_value
    where = dotted(path)
    if kind == "additionalProperties":
        allowed = sorted(sub.get("properties", {}))
        extra = sorted(set(inst) - set(allowed)) if isinstance(inst, dict) else []
        pattern = sub.get("patternProperties")
        if pattern:
            import re

            extra = [k for k in extra if not any(re.search(p, k) for p in pattern)]
        key = extra[0] if extra else "?"
        hint = f" (allowed: {', '.join(allowed)})" if allowed and len(allowed) <= 60 else ""
        return path + (key,), f"unknown key {key!r} in {where}{hint}", True
    # a subschema whose description starts "Fix: " tells the map's author what to write and why
    advice = sub.get("description")
    why = f"; {advice[5:]}" if isinstance(advice, str) and advice.startswith("Fix: ") else ""
    if kind == "required":
        missing = error.message.split("'")[1] if "'" in error.message else "?"
        return path, f"{where}: missing required key {missing!r}{why}", False
    if kind == "type":
        expected = value
        names = [str(_TYPE_NAMES.get(t, t)) for t in (expected if isinstance(expected, list) else [expected])]
        return path, f"{where}: expected {' or '.join(names)}, got {short(inst)}", False
    if kind == "enum":
        options = ", ".join(repr(v) for v in value)
        return path, f"{where}: {short(inst)} is not one of {options}", False
    if kind == "const":
        return path, f"{where}: must be {value!r}, got {short(inst)}{why}", False
    if kind == "pattern":
        return path, f"{where}: {short(inst)} does not match the pattern {value}", False
    if kind in ("minimum", "maximum", "exclusiveMinimum", "exclusiveMaximum"):
        rel = {"minimum": "less than the minimum", "maximum": "greater than the maximum",
               "exclusiveMinimum": "not greater than", "exclusiveMaximum": "not less than"}[kind]
        return path, f"{where}: {short(inst)} is {rel} {value}", False
    if kind in ("minItems", "maxItems", "minLength", "maxLength"):
        return path, f"{where}: {kind} is {value}", False
    if kind == "uniqueItems":
        return path, f"{where}: items must be unique", False
    if kind == "propertyNames":
        return path, f"{where}: bad key name ({error.message})", True
    return path, f"{where}: {error.message[:200]}", False


def validate(doc: Document, schema_path: Path = SCHEMA_PATH) -> list[Diagnostic]:
    """Every error of a document against the schema in ``schema_path`` (default: the map schema), located."""
    diagnostics: list[Diagnostic] = []
    seen: set[tuple[PathT, str]] = set()
    for raw in validator(schema_path).iter_errors(doc.data):
        error = _leaf(raw)
        path, message, at_key = _message(error)
        if error.validator == "propertyNames":
            bad = error.instance
            path = path + (bad,) if isinstance(bad, str) else path
        if (path, message) in seen:
            continue
        seen.add((path, message))
        diagnostics.append(Diagnostic(doc.positions.at(path, key=at_key), message))
    return diagnostics

"""The map schema file itself: valid JSON Schema 2020-12, only vocabulary keys, one source of truth."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import jsonschema
import pytest

from drivemap.frontend.schema import SCHEMA_PATH

ROOT = Path(__file__).resolve().parents[2]
TOP_LEVEL = ROOT / "schemas" / "drivemap.schema.json"

#: The keywords of JSON Schema 2020-12 (core, applicator, validation, unevaluated, meta-data,
#: format-annotation, content vocabularies).
VOCABULARY = {
    "$schema", "$id", "$ref", "$defs", "$comment", "$anchor", "$dynamicRef", "$dynamicAnchor", "$vocabulary",
    "title", "description", "default", "examples", "deprecated", "readOnly", "writeOnly",
    "type", "enum", "const", "multipleOf", "maximum", "exclusiveMaximum", "minimum", "exclusiveMinimum",
    "maxLength", "minLength", "pattern", "maxItems", "minItems", "uniqueItems", "maxContains", "minContains",
    "maxProperties", "minProperties", "required", "dependentRequired",
    "properties", "patternProperties", "additionalProperties", "propertyNames", "items", "prefixItems",
    "contains", "unevaluatedItems", "unevaluatedProperties", "allOf", "anyOf", "oneOf", "not", "if", "then",
    "else", "dependentSchemas", "format", "contentEncoding", "contentMediaType", "contentSchema",
}
NAMED = {"properties", "patternProperties", "$defs", "dependentSchemas"}        # name -> schema
SINGLE = {"items", "not", "if", "then", "else", "contains", "additionalProperties", "propertyNames",
          "unevaluatedProperties", "unevaluatedItems", "contentSchema"}          # one subschema
LISTS = {"allOf", "anyOf", "oneOf", "prefixItems"}                                # list of subschemas


def stray_keys(node: Any, path: str = "#") -> list[str]:
    """Every key of a (sub)schema that is not a 2020-12 keyword, as a JSON pointer."""
    if not isinstance(node, dict):
        return []
    found = [f"{path}/{key}" for key in node if key not in VOCABULARY]
    for key, value in node.items():
        if key in NAMED and isinstance(value, dict):
            for name, sub in value.items():
                found += stray_keys(sub, f"{path}/{key}/{name}")
        elif key in SINGLE:
            found += stray_keys(value, f"{path}/{key}")
        elif key in LISTS and isinstance(value, list):
            for i, sub in enumerate(value):
                found += stray_keys(sub, f"{path}/{key}/{i}")
    return found


SCHEMAS = sorted((ROOT / "schemas").glob("*.schema.json"))


@pytest.mark.parametrize("path", SCHEMAS, ids=lambda p: p.name)
def test_schema_is_valid_against_the_2020_12_meta_schema(path: Path) -> None:
    schema = json.loads(path.read_text(encoding="utf-8"))
    assert schema["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    jsonschema.Draft202012Validator.check_schema(schema)


@pytest.mark.parametrize("path", SCHEMAS, ids=lambda p: p.name)
def test_schema_has_no_key_outside_the_vocabulary(path: Path) -> None:
    assert stray_keys(json.loads(path.read_text(encoding="utf-8"))) == []


def test_the_vocabulary_check_finds_a_stray_key() -> None:
    """The check itself can fail: a description cut in two is found where it is."""
    broken = {"properties": {"vendor": {"description": "Vendor name", "else null.": None, "type": "string"}}}
    assert stray_keys(broken) == ["#/properties/vendor/else null."]


def test_every_property_has_a_description() -> None:
    missing: list[str] = []

    def walk(node: Any, path: str) -> None:
        if isinstance(node, dict):
            for name, sub in node.get("properties", {}).items():
                if isinstance(sub, dict) and "description" not in sub and "$ref" not in sub:
                    missing.append(f"{path}/properties/{name}")
            for key, value in node.items():
                walk(value, f"{path}/{key}")
        elif isinstance(node, list):
            for i, item in enumerate(node):
                walk(item, f"{path}/{i}")

    walk(json.loads(TOP_LEVEL.read_text(encoding="utf-8")), "#")
    assert missing == []


@pytest.mark.parametrize("path", SCHEMAS, ids=lambda p: p.name)
def test_the_packaged_schemas_are_the_top_level_files(path: Path) -> None:
    """The package reads each schema through a link to schemas/ (the wheel test checks the copies)."""
    packaged = SCHEMA_PATH.parent / path.name
    assert packaged.read_bytes() == path.read_bytes()
    assert packaged.resolve() == path.resolve()

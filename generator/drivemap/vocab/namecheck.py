"""Every generated name checked against every other generated name and every fixed output file.

A map's names become Python classes, attributes and fields, docs anchors and file names. Each is
checked against what the generated code and files already hold (:func:`drivemap.vocab.reserved.reserved`,
read from the templates' real output) and against each other:

* the model id against the files written once for all models (``index`` would overwrite the docs
  index);
* enum, bit-field and exception classes against the names the generated modules import and define
  (``ReadWrite``, ``Field``, ``Any``, ``IntCodec`` ...), against keywords, and against each other
  (two exceptions giving one class);
* register names against the builtins the generated classes name in annotations (``float``,
  ``tuple``) and against every attribute of a generated client;
* bit-field attributes of a record register against each other (``IF`` and ``IF_`` both give
  ``if_``) and against those builtins;
* enum member names against the pseudo-members ``UNKNOWN_<n>`` of unnamed values;
* group names against each other, and every heading anchor of the docs page against every other
  (``Parity`` / ``PARITY``, a group titled ``Enums``).

:func:`problems` yields (where, message, options of :meth:`Checker.error`).
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from typing import Any

from drivemap.diagnostics import Problem
from drivemap.model.nodes import camel, is_keyword
from drivemap.runtime.names import FIXED_NAMES, UNKNOWN_MEMBER, bit_attribute, exception_classes
from drivemap.vocab.escape import md_text, slug
from drivemap.vocab.reserved import reserved

__all__ = ["CLIENT_ATTRIBUTES", "docs_problems", "python_problems"]

#: Attribute names of the generated clients that a register may not take.
CLIENT_ATTRIBUTES = frozenset(
    {
        "read", "write", "read_all", "read_by_name", "write_by_name", "read_modify_write", "close",
        "stats", "bus", "unit", "pending_configuration", "pending_power_cycle", "apply_configuration",
        "registers", "accessor", "tcp", "serial", "rtu_over_tcp", "broadcast", "model", "page_policy",
        "connect", "plan", "loopback", "write_many", "self", "cls", "holes", "read_registers",
    }
)



def python_problems(data: dict[str, Any]) -> Iterator[Problem]:
    """Every collision of a map's names with the generated Python package (the python exporter's hook)."""
    yield from _model_id(data, "python")
    yield from _classes(data)
    yield from _registers(data)
    yield from _bits(data)
    yield from _enum_members(data)


def docs_problems(data: dict[str, Any]) -> Iterator[Problem]:
    """Every collision of a map's names on its generated docs page (the docs exporter's hook)."""
    yield from _model_id(data, "docs")
    yield from _groups(data)
    yield from _anchors(data)


def _model_id(data: dict[str, Any], only: str) -> Iterator[Problem]:
    model = data["device"]["model"]
    for exporter, per_model, once in reserved().outputs:
        if exporter != only:
            continue
        for pattern in sorted(per_model):
            path = pattern.replace("{model}", model)
            clash = next((f for f in sorted(once) if f == path or f.startswith(path + "/")
                          or path.startswith(f + "/")), None)
            if clash is not None:
                yield (("device", "model"), f"model id {model!r} would write {path}, the file the {exporter} exporter "
                                            "writes once for all models; choose another id", {})


def _bits_class_names(data: dict[str, Any]) -> Iterator[tuple[str, tuple[str | int, ...]]]:
    for i, reg in enumerate(data["registers"]):
        if reg.get("bits"):
            yield reg.get("flags_name") or camel(reg["name"]), ("registers", i, "flags_name" if reg.get("flags_name")
                                                                 else "name")


def _classes(data: dict[str, Any]) -> Iterator[Problem]:
    taken = reserved().module
    owners: dict[str, tuple[str, tuple[str | int, ...]]] = {}
    for name in data.get("enums", {}):
        where: tuple[str | int, ...] = ("enums", name)
        if name in FIXED_NAMES:
            yield where, f"enum name {name!r} is taken by the generated client package", {"key": True}
        else:
            if name in taken:
                yield where, f"enum name {name!r} is a name the generated client module imports or defines", {"key": True}
            elif is_keyword(name):
                yield where, f"enum name {name!r} is a Python keyword", {"key": True}
        owners.setdefault(name, (f"enum {name}", where))
    for cls, where in _bits_class_names(data):
        if cls in FIXED_NAMES:
            yield where, f"bit-field class name {cls!r} is taken by the generated client package", {}
        elif cls in taken:
            yield where, f"bit-field class name {cls!r} is a name the generated client module imports or defines", {}
        elif is_keyword(cls):
            yield where, f"bit-field class name {cls!r} is a Python keyword", {}
        owners.setdefault(cls, (f"the bit-field class of registers[{where[1]}]", where))
    exceptions = data["protocol"]["exceptions"]
    classes = exception_classes([(e["name"], e["code"]) for e in exceptions])
    for i, cls in enumerate(classes):
        where = ("protocol", "exceptions", i, "name")
        other = owners.get(cls)
        if cls in taken:
            yield where, f"exception {exceptions[i]['name']!r} becomes class {cls!r}, a name the generated client " \
                         "module imports or defines", {}
        elif other is not None:
            yield where, f"exception {exceptions[i]['name']!r} becomes class {cls!r}, which {other[0]} also defines", {
                "related": other[1], "note": "defined here", "related_key": other[1][0] == "enums"}
        owners.setdefault(cls, (f"exception {exceptions[i]['name']!r}", where))


def _registers(data: dict[str, Any]) -> Iterator[Problem]:
    shadowed = reserved().annotation
    attributes = reserved().client
    seen: set[str] = set()
    for i, reg in enumerate(data["registers"]):
        name = reg["name"]
        if name in seen or is_keyword(name):
            continue  # reported by the register checks
        seen.add(name)
        where: tuple[str | int, ...] = ("registers", i, "name")
        if name in CLIENT_ATTRIBUTES:
            yield where, f"register name {name!r} clashes with a client attribute", {}
        elif name in shadowed:
            yield where, f"register name {name!r} would shadow the builtin {name!r} in the generated classes", {}
        elif name in attributes:
            yield where, f"register name {name!r} clashes with a client attribute", {}


def _is_record(reg: dict[str, Any]) -> bool:
    """Rendered as a frozen dataclass (multi-bit or enumerated fields), as :func:`views.client.bits_kind` says."""
    return any(b.get("width", 1) > 1 or b.get("enum") for b in reg.get("bits", ()))


def _bits(data: dict[str, Any]) -> Iterator[Problem]:
    shadowed = reserved().annotation
    for i, reg in enumerate(data["registers"]):
        if not _is_record(reg):
            continue
        attributes: dict[str, int] = {}
        for j, bit in enumerate(reg["bits"]):
            attr = bit_attribute(bit["name"])
            where: tuple[str | int, ...] = ("registers", i, "bits", j, "name")
            if attr in attributes and reg["bits"][attributes[attr]]["name"] != bit["name"]:
                first = reg["bits"][attributes[attr]]["name"]
                yield where, f"bit fields {first!r} and {bit['name']!r} both become the attribute {attr!r}", {
                    "related": ("registers", i, "bits", attributes[attr], "name")}
            elif attr in shadowed:
                yield where, f"bit field {bit['name']!r} becomes the attribute {attr!r}, which would shadow the " \
                             "builtin in the generated class", {}
            attributes.setdefault(attr, j)


def _enum_members(data: dict[str, Any]) -> Iterator[Problem]:
    pseudo = re.compile(re.escape(UNKNOWN_MEMBER) + r"-?\d+$")
    for name, enum in data.get("enums", {}).items():
        for j, item in enumerate(enum["values"]):
            if pseudo.match(item["name"]):
                yield ("enums", name, "values", j, "name"), (
                    f"enum member {item['name']!r} looks like the name a generated enum gives a value the map "
                    f"does not name ({UNKNOWN_MEMBER}<value>)"), {}


def _groups(data: dict[str, Any]) -> Iterator[Problem]:
    seen: dict[str, int] = {}
    for i, group in enumerate(data.get("groups", ())):
        if group["name"] in seen:
            yield ("groups", i, "name"), f"duplicate group name {group['name']!r}", {
                "related": ("groups", seen[group["name"]], "name")}
        seen.setdefault(group["name"], i)


def _anchors(data: dict[str, Any]) -> Iterator[Problem]:
    """Headings of the model's docs page whose anchors collide (a link to one would lead to the other)."""
    owners: dict[str, tuple[str, tuple[str | int, ...] | None]] = {a: ("a fixed section of the page", None) for a in reserved().headings}
    headings: list[tuple[str, tuple[str | int, ...], dict[str, Any]]] = []
    for i, port in enumerate(data["protocol"]["ports"]):
        headings.append((f"Port {md_text(port['name'])}", ("protocol", "ports", i, "name"), {}))
    for i, group in enumerate(data.get("groups", ())):
        headings.append((md_text(group["title"]), ("groups", i, "title"), {}))
    for name in data.get("enums", {}):
        headings.append((f"Enum {name}", ("enums", name), {"key": True}))
    names = {reg["name"]: i for i, reg in reversed(list(enumerate(data["registers"])))}
    for name, i in names.items():  # a repeated register or example name is reported by its own check
        if data["registers"][i].get("bits"):
            headings.append((f"Bits of {name}", ("registers", i, "name"), {}))
    examples = {ex["name"]: i for i, ex in reversed(list(enumerate(data["examples"])))}
    for name, i in examples.items():
        headings.append((f"Example {name}", ("examples", i, "name"), {}))
    for i, issue in enumerate(data.get("known_issues", ())):
        headings.append((f"{i + 1}. {md_text(issue['title'])}", ("known_issues", i, "title"), {}))
    for text, where, options in headings:
        anchor = slug(text)
        other = owners.get(anchor)
        if other is None:
            owners[anchor] = (f"the heading {text!r}", where)
            continue
        extra: dict[str, Any] = dict(options)
        if other[1] is not None:
            extra.update(related=other[1], note="the other heading comes from here",
                         related_key=other[1][0] == "enums")
        yield where, f"docs heading {text!r} gets the anchor #{anchor}, as {other[0]} does", extra

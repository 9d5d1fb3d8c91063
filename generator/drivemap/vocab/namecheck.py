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

:func:`python_problems` and :func:`docs_problems` walk the compiled model (not the YAML dict) and yield
(YAML path, message, options of :meth:`Checker.error`), each path taken from the node's own source
reference (``src``; the same index path where a model was built without one).
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from typing import Any

from drivemap.diagnostics import Problem
from drivemap.model.nodes import Model, camel, is_keyword
from drivemap.model.source import YamlPath
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



def _at(node: object, fallback: YamlPath, *tail: str | int) -> YamlPath:
    """The node's YAML path (its ``src``), else ``fallback``; then ``tail``."""
    src = getattr(node, "src", None)
    return (*(src.yaml_path if src is not None else fallback), *tail)


def python_problems(model: Model) -> Iterator[Problem]:
    """Every collision of a map's names with the generated Python package (the python exporter's hook)."""
    yield from _model_id(model, "python")
    yield from _classes(model)
    yield from _registers(model)
    yield from _bits(model)
    yield from _enum_members(model)


def docs_problems(model: Model) -> Iterator[Problem]:
    """Every collision of a map's names on its generated docs page (the docs exporter's hook)."""
    yield from _model_id(model, "docs")
    yield from _groups(model)
    yield from _anchors(model)


def _model_id(model: Model, only: str) -> Iterator[Problem]:
    name = model.name
    for exporter, per_model, once in reserved().outputs:
        if exporter != only:
            continue
        for pattern in sorted(per_model):
            path = pattern.replace("{model}", name)
            clash = next((f for f in sorted(once) if f == path or f.startswith(path + "/")
                          or path.startswith(f + "/")), None)
            if clash is not None:
                yield (("device", "model"), f"model id {name!r} would write {path}, the file the {exporter} exporter "
                                            "writes once for all models; choose another id", {})


def _bits_class_names(model: Model) -> Iterator[tuple[str, YamlPath]]:
    for i, reg in enumerate(model.registers):
        if reg.bits:
            yield reg.flags_name or camel(reg.name), _at(reg, ("registers", i), "flags_name" if reg.flags_name
                                                          else "name")


def _classes(model: Model) -> Iterator[Problem]:
    taken = reserved().module
    owners: dict[str, tuple[str, YamlPath]] = {}
    for enum in model.enums:
        name = enum.name
        where = _at(enum, ("enums", name))
        if name in FIXED_NAMES:
            yield where, f"enum name {name!r} is taken by the generated client package", {"key": True}
        else:
            if name in taken:
                yield where, f"enum name {name!r} is a name the generated client module imports or defines", {"key": True}
            elif is_keyword(name):
                yield where, f"enum name {name!r} is a Python keyword", {"key": True}
        owners.setdefault(name, (f"enum {name}", where))
    for cls, where in _bits_class_names(model):
        if cls in FIXED_NAMES:
            yield where, f"bit-field class name {cls!r} is taken by the generated client package", {}
        elif cls in taken:
            yield where, f"bit-field class name {cls!r} is a name the generated client module imports or defines", {}
        elif is_keyword(cls):
            yield where, f"bit-field class name {cls!r} is a Python keyword", {}
        owners.setdefault(cls, (f"the bit-field class of registers[{where[1]}]", where))
    exceptions = model.protocol.exceptions
    classes = exception_classes([(e.name, e.code) for e in exceptions])
    for i, cls in enumerate(classes):
        exc = exceptions[i]
        where = _at(exc, ("protocol", "exceptions", i), "name")
        other = owners.get(cls)
        if cls in taken:
            yield where, f"exception {exc.name!r} becomes class {cls!r}, a name the generated client " \
                         "module imports or defines", {}
        elif other is not None:
            yield where, f"exception {exc.name!r} becomes class {cls!r}, which {other[0]} also defines", {
                "related": other[1], "note": "defined here", "related_key": other[1][0] == "enums"}
        owners.setdefault(cls, (f"exception {exc.name!r}", where))


def _registers(model: Model) -> Iterator[Problem]:
    shadowed = reserved().annotation
    attributes = reserved().client
    seen: set[str] = set()
    for i, reg in enumerate(model.registers):
        name = reg.name
        if name in seen or is_keyword(name):
            continue  # reported by the register checks
        seen.add(name)
        where = _at(reg, ("registers", i), "name")
        if name in CLIENT_ATTRIBUTES:
            yield where, f"register name {name!r} clashes with a client attribute", {}
        elif name in shadowed:
            yield where, f"register name {name!r} would shadow the builtin {name!r} in the generated classes", {}
        elif name in attributes:
            yield where, f"register name {name!r} clashes with a client attribute", {}


def _bits(model: Model) -> Iterator[Problem]:
    """Bit-field attributes of a register rendered as a frozen dataclass (multi-bit or enumerated fields,
    as :func:`views.client.bits_kind` says)."""
    shadowed = reserved().annotation
    for i, reg in enumerate(model.registers):
        if not any(b.width > 1 or b.enum for b in reg.bits):
            continue
        attributes: dict[str, int] = {}
        for j, bit in enumerate(reg.bits):
            attr = bit_attribute(bit.name)
            where = _at(bit, ("registers", i, "bits", j), "name")
            if attr in attributes and reg.bits[attributes[attr]].name != bit.name:
                first = reg.bits[attributes[attr]]
                yield where, f"bit fields {first.name!r} and {bit.name!r} both become the attribute {attr!r}", {
                    "related": _at(first, ("registers", i, "bits", attributes[attr]), "name")}
            elif attr in shadowed:
                yield where, f"bit field {bit.name!r} becomes the attribute {attr!r}, which would shadow the " \
                             "builtin in the generated class", {}
            attributes.setdefault(attr, j)


def _enum_members(model: Model) -> Iterator[Problem]:
    pseudo = re.compile(re.escape(UNKNOWN_MEMBER) + r"-?\d+$")
    for enum in model.enums:
        for j, member in enumerate(enum.members):
            if pseudo.match(member.name):
                yield _at(member, ("enums", enum.name, "values", j), "name"), (
                    f"enum member {member.name!r} looks like the name a generated enum gives a value the map "
                    f"does not name ({UNKNOWN_MEMBER}<value>)"), {}


def _groups(model: Model) -> Iterator[Problem]:
    seen: dict[str, YamlPath] = {}
    for i, group in enumerate(model.groups):
        where = _at(group, ("groups", i), "name")
        if group.name in seen:
            yield where, f"duplicate group name {group.name!r}", {"related": seen[group.name]}
        seen.setdefault(group.name, where)


def _anchors(model: Model) -> Iterator[Problem]:
    """Headings of the model's docs page whose anchors collide (a link to one would lead to the other)."""
    owners: dict[str, tuple[str, YamlPath | None]] = {a: ("a fixed section of the page", None) for a in reserved().headings}
    headings: list[tuple[str, YamlPath, dict[str, Any]]] = []
    for i, port in enumerate(model.protocol.ports):
        headings.append((f"Port {md_text(port.name)}", _at(port, ("protocol", "ports", i), "name"), {}))
    for i, group in enumerate(model.groups):
        headings.append((md_text(group.title), _at(group, ("groups", i), "title"), {}))
    for enum in model.enums:
        headings.append((f"Enum {enum.name}", _at(enum, ("enums", enum.name)), {"key": True}))
    for i, reg in enumerate(model.registers):
        if reg.bits:
            headings.append((f"Bits of {reg.name}", _at(reg, ("registers", i), "name"), {}))
    for i, ex in enumerate(model.examples):
        headings.append((f"Example {ex.name}", _at(ex, ("examples", i), "name"), {}))
    for i, issue in enumerate(model.known_issues):
        headings.append((f"{i + 1}. {md_text(issue.title)}", _at(issue, ("known_issues", i), "title"), {}))
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

"""Typed exporter options: one schema read from the command line and from ``pyproject.toml``.

An exporter declares its options as a frozen dataclass (``options_class``), each field made by
:func:`option` with its help text. The same class then

* adds the options to ``drivemap export --format NAME``'s parser (:meth:`ExporterOptions.add_arguments`):
  ``--long-name`` per field, a flag for a ``bool``, a repeatable option for a ``tuple``, ``int``
  values parsed, choices and mutually exclusive sets checked by argparse;
* reads the ``options`` table of a committed export (``[[tool.drivemap.exports]]``) directly
  (:meth:`ExporterOptions.from_table`): the same names (``ha-version`` or ``ha_version``), ``true``
  for a flag, a list (or one value) for a repeatable option, the same checks and messages, without
  turning the table back into a command line;
* is what the exporter reads (:meth:`ExporterOptions.from_values`): a frozen, typed object.

``Options.values`` (the mapping of option names to values) stays what a third-party exporter that
adds its own arguments reads.
"""

from __future__ import annotations

import argparse
import dataclasses
import typing
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar, Literal, TypeVar

from drivemap.backends.common import OptionError

__all__ = ["DEFAULT_SCAN_S", "DEFAULT_SETTINGS_S", "ExporterOptions", "NoOptions", "SERIAL_GROUP", "SelectionOptions", "SerialOptions",
           "option"]

#: Polling interval (s) of live groups, and of groups that hold only writable settings, unless an option says.
DEFAULT_SCAN_S = 15
DEFAULT_SETTINGS_S = 300

_O = TypeVar("_O", bound="ExporterOptions")
_Kind = Literal["flag", "int", "text", "repeat"]


@dataclass(frozen=True)
class _Meta:
    help: str
    metavar: str | None
    choices: tuple[Any, ...] | None
    group: str | None
    exclusive: str | None


def option(default: Any = None, *, help: str | None = None, metavar: str | None = None,  # noqa: A002 - argparse's word
           choices: Sequence[Any] | None = None, group: str | None = None, exclusive: str | None = None) -> Any:
    """A field of an options class: its default, help text and checks. ``group`` names the titled
    group it is listed under in ``--help``; options sharing an ``exclusive`` name exclude each other."""
    meta = _Meta(help or "", metavar, tuple(choices) if choices is not None else None, group, exclusive)
    return field(default=default, metadata={"option": meta})


@dataclass(frozen=True)
class _Option:
    name: str  # the dataclass field (argparse's dest)
    kind: _Kind
    default: Any
    meta: _Meta

    @property
    def flag(self) -> str:
        return "--" + self.name.replace("_", "-")


def _kind(hint: Any) -> _Kind:
    args = [a for a in typing.get_args(hint) if a is not type(None)] or [hint]
    base = args[0]
    if base is bool:
        return "flag"
    if base is int:
        return "int"
    if typing.get_origin(base) is tuple:
        return "repeat"
    return "text"


@dataclass(frozen=True)
class ExporterOptions:
    """Base of every exporter's options class (see the module docstring)."""

    _SCHEMA: ClassVar[dict[type, tuple[_Option, ...]]] = {}

    @classmethod
    def schema(cls) -> tuple[_Option, ...]:
        """The options, the class's own first, then those of its bases in method resolution order
        (each in declaration order, an option a class redefines where its base declared it; ``--help``
        lists them so). Read once per class."""
        if cls not in ExporterOptions._SCHEMA:
            hints = typing.get_type_hints(cls)
            fields = {f.name: f for f in dataclasses.fields(cls) if "option" in f.metadata}
            declared = {n: klass for klass in cls.__mro__ for n in vars(klass).get("__annotations__", {})}  # the deepest
            order = [n for klass in cls.__mro__ for n in vars(klass).get("__annotations__", {})
                     if n in fields and declared[n] is klass]
            ExporterOptions._SCHEMA[cls] = tuple(
                _Option(n, _kind(hints[n]), fields[n].default, fields[n].metadata["option"]) for n in order)
        return ExporterOptions._SCHEMA[cls]

    @classmethod
    def add_arguments(cls, parser: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
        """Add every option to ``parser`` (titled groups and exclusive sets as declared)."""
        groups: dict[str | None, Any] = {None: parser}
        exclusive: dict[tuple[str | None, str], Any] = {}
        for opt in cls.schema():
            where = groups.get(opt.meta.group)
            if where is None:
                where = groups[opt.meta.group] = parser.add_argument_group(opt.meta.group)
            if opt.meta.exclusive is not None:
                key = (opt.meta.group, opt.meta.exclusive)
                if key not in exclusive:
                    exclusive[key] = where.add_mutually_exclusive_group()
                where = exclusive[key]
            kwargs: dict[str, Any] = {"help": opt.meta.help} if opt.meta.help else {}
            if opt.kind == "flag":
                where.add_argument(opt.flag, action="store_true", **kwargs)
                continue
            kwargs["default"] = opt.default
            if opt.meta.metavar is not None:
                kwargs["metavar"] = opt.meta.metavar
            if opt.meta.choices is not None:
                kwargs["choices"] = list(opt.meta.choices)
            if opt.kind == "int":
                kwargs["type"] = int
            if opt.kind == "repeat":
                kwargs["action"] = "append"
            where.add_argument(opt.flag, **kwargs)

    @classmethod
    def from_values(cls: type[_O], values: Mapping[str, Any]) -> _O:
        """The options from a mapping of option names (argparse's ``dest``) to values; names this
        class does not know are left to the exporter's other readers."""
        given: dict[str, Any] = {}
        for opt in cls.schema():
            value = values.get(opt.name, opt.default)
            if opt.kind == "repeat" and value is not None:
                value = tuple(value)
            given[opt.name] = value
        return cls(**given)

    @classmethod
    def from_table(cls: type[_O], table: Mapping[str, Any]) -> _O:
        """The options of a committed export's ``options`` table, checked as the command line checks
        them (:class:`OptionError` with argparse's wording)."""
        by_name = {opt.name: opt for opt in cls.schema()}
        given: dict[str, Any] = {}
        for key, value in table.items():
            opt = by_name.get(str(key).replace("-", "_"))
            if opt is None:
                known = ", ".join(sorted(o.flag.lstrip("-") for o in by_name.values())) or "none"
                raise OptionError(f"unknown option {key!r} (options: {known})")
            read = _from_toml(opt, value)
            if read is not None:
                given[opt.name] = read
        _check_exclusive(cls.schema(), given)
        return cls.from_values(given)

    def values(self) -> dict[str, Any]:
        """The options as a mapping of option names to values (what ``Options.values`` holds)."""
        return {opt.name: getattr(self, opt.name) for opt in self.schema()}


def _from_toml(opt: _Option, value: Any) -> Any:
    """One option's TOML value as the command line would have read it (None: not given)."""
    if opt.kind == "flag":
        if not isinstance(value, bool):
            raise OptionError(f"argument {opt.flag}: a flag takes true or false, not {value!r}")
        return True if value else None
    items = value if isinstance(value, list) else [value]
    if opt.kind != "repeat" and len(items) != 1:
        raise OptionError(f"argument {opt.flag}: expected one value, got a list")
    read = [_scalar(opt, item) for item in items]
    return read if opt.kind == "repeat" else read[0]


def _scalar(opt: _Option, item: Any) -> Any:
    if isinstance(item, (dict, list, bool)):
        raise OptionError(f"argument {opt.flag}: invalid value: {item!r}")
    text = str(item)  # what the command line would carry
    value: Any = text
    if opt.kind == "int":
        try:
            value = int(text)
        except ValueError:
            raise OptionError(f"argument {opt.flag}: invalid int value: {text!r}") from None
    choices = opt.meta.choices
    if choices is not None and value not in choices:
        shown = ", ".join(repr(c) for c in choices)
        raise OptionError(f"argument {opt.flag}: invalid choice: {value!r} (choose from {shown})")
    return value


def _check_exclusive(schema: Sequence[_Option], given: Mapping[str, Any]) -> None:
    seen: dict[tuple[str | None, str], _Option] = {}
    for opt in schema:
        if opt.meta.exclusive is None or given.get(opt.name) is None:
            continue
        key = (opt.meta.group, opt.meta.exclusive)
        if key in seen:
            raise OptionError(f"argument {opt.flag}: not allowed with argument {seen[key].flag}")
        seen[key] = opt


@dataclass(frozen=True)
class NoOptions(ExporterOptions):
    """The options of an exporter that has none."""


@dataclass(frozen=True)
class SelectionOptions(ExporterOptions):
    """Which registers an integration export covers and how often it polls them (``views.integrations``)."""

    unit: int | None = option(help="unit id of the device (default: 1, or the map's lowest)")
    only: tuple[str, ...] | None = option(metavar="GROUP", help="export only the registers of this group (repeatable)")
    page: tuple[str, ...] | None = option(
        metavar="SELECTOR=VALUE", help="the page a page selector shows (default: its map default, else its lowest page)")
    scan_interval: int | None = option(metavar="SECONDS", help=f"polling interval of live groups (default {DEFAULT_SCAN_S})")
    settings_interval: int | None = option(
        metavar="SECONDS", help=f"polling interval of groups that hold only writable settings (default {DEFAULT_SETTINGS_S})")
    interval: tuple[str, ...] | None = option(metavar="GROUP=SECONDS", help="polling interval of one group (repeatable)")
    name_prefix: str | None = option(metavar="TEXT", help="prefix of every entity name (default: the model id)")


SERIAL_GROUP = "serial line (the map's defaults where it gives them)"


@dataclass(frozen=True)
class SerialOptions(ExporterOptions):
    """The serial line of an integration export (``views.integrations.serial_settings``)."""

    port: str | None = option(metavar="NAME", group=SERIAL_GROUP, help="which port of the map (default: its first that fits)")
    method: str | None = option(choices=("rtu", "ascii"), group=SERIAL_GROUP, help="framing")
    baudrate: int | None = option(group=SERIAL_GROUP)
    parity: str | None = option(choices=("none", "even", "odd"), group=SERIAL_GROUP)
    bytesize: int | None = option(choices=(7, 8), group=SERIAL_GROUP)
    stopbits: int | None = option(choices=(1, 2), group=SERIAL_GROUP)

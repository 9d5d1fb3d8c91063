"""Typed exporter options (backends/options.py): one schema builds ``drivemap export``'s parser and
reads a committed export's ``options`` table, with the same values and the same refusals."""

from __future__ import annotations

import argparse
import dataclasses
from typing import Any

import pytest

from drivemap.backends.common import OptionError
from drivemap.backends.exporters import available
from drivemap.backends.options import ExporterOptions, SelectionOptions, option
from drivemap.build import entry_options

EXPORTERS = available()


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> Any:
        raise OptionError(message)


def _argv(exporter: Any, argv: list[str]) -> dict[str, Any]:
    parser = _Parser(prog=exporter.name, add_help=False)
    exporter.add_arguments(parser)
    return vars(parser.parse_args(argv))


#: (format, TOML table, the same options on the command line)
SAME = [
    ("csv", {}, []),
    ("csv", {"delimiter": "semicolon", "bom": True}, ["--delimiter", "semicolon", "--bom"]),
    ("csv", {"bom": False}, []),
    ("homeassistant", {"tcp": "127.0.0.1:502", "page": ["a=1", "b=2"], "ha-version": "2024.3"},
     ["--tcp", "127.0.0.1:502", "--page", "a=1", "--page", "b=2", "--ha-version", "2024.3"]),
    ("homeassistant", {"only": "monitor", "scan_interval": 7, "baudrate": "19200", "parity": "even"},
     ["--only", "monitor", "--scan-interval", "7", "--baudrate", "19200", "--parity", "even"]),
    ("esphome", {"no-network": True, "flow-control-pin": "GPIO4", "stopbits": 2, "method": "rtu"},
     ["--no-network", "--flow-control-pin", "GPIO4", "--stopbits", "2", "--method", "rtu"]),
    ("pymodbus-sim", {"serial": "/dev/ttyS0", "unit": 3}, ["--serial", "/dev/ttyS0", "--unit", "3"]),
]


@pytest.mark.parametrize(("fmt", "table", "argv"), SAME)
def test_a_table_reads_as_the_command_line(fmt: str, table: dict[str, Any], argv: list[str]) -> None:
    exporter = EXPORTERS[fmt]()
    from_table, from_argv = entry_options(exporter, table), _argv(exporter, argv)
    assert exporter.options_class.from_values(from_table) == exporter.options_class.from_values(from_argv)
    assert {k: v for k, v in from_table.items() if v not in (None, False)} == {
        k: tuple(v) if isinstance(v, list) else v for k, v in from_argv.items() if v not in (None, False)}


#: (format, TOML table, what the refusal says, the same on the command line or None)
REFUSED = [
    ("csv", {"colour": "red"}, "unknown option 'colour' (options: bom, delimiter)", None),
    ("csv", {"delimiter": "pipe"}, "argument --delimiter: invalid choice: 'pipe'", ["--delimiter", "pipe"]),
    ("csv", {"bom": "yes"}, "argument --bom: a flag takes true or false", None),
    ("homeassistant", {"tcp": "h:1", "serial": "/dev/x"}, "argument --serial: not allowed with argument --tcp",
     ["--tcp", "h:1", "--serial", "/dev/x"]),
    ("homeassistant", {"baudrate": "fast"}, "argument --baudrate: invalid int value: 'fast'", ["--baudrate", "fast"]),
    ("homeassistant", {"hub-name": ["a", "b"]}, "argument --hub-name: expected one value", None),
    ("homeassistant", {"unit": True}, "argument --unit: invalid value: True", None),
    ("esphome", {"method": "ascii"}, "argument --method: invalid choice: 'ascii'", ["--method", "ascii"]),
    ("json", {"anything": 1}, "unknown option 'anything' (options: none)", None),
]


@pytest.mark.parametrize(("fmt", "table", "message", "argv"), REFUSED)
def test_a_table_is_refused_as_the_command_line_refuses(fmt: str, table: dict[str, Any], message: str,
                                                         argv: list[str] | None) -> None:
    exporter = EXPORTERS[fmt]()
    with pytest.raises(OptionError) as from_table:
        entry_options(exporter, table)
    assert message in str(from_table.value)
    if argv is not None:
        with pytest.raises(OptionError) as from_argv:
            _argv(exporter, argv)
        assert str(from_argv.value).startswith(message.split(":")[0] + ":")
        assert message.split(": ", 1)[1].split(" (")[0] in str(from_argv.value)


def test_the_options_an_exporter_reads_are_typed_and_frozen() -> None:
    cls = EXPORTERS["homeassistant"].options_class
    own = cls.from_values(_argv(EXPORTERS["homeassistant"](), ["--page", "a=1", "--unit", "4"]))
    assert own.page == ("a=1",) and own.unit == 4 and own.tcp is None  # type: ignore[attr-defined]
    with pytest.raises(dataclasses.FrozenInstanceError):
        own.unit = 5  # type: ignore[attr-defined]
    assert isinstance(own, SelectionOptions)


def test_a_plugin_that_adds_its_own_arguments_keeps_its_parser() -> None:
    from drivemap.backends.exporters.base import Exporter

    class Legacy(Exporter):
        name = "legacy"

        def add_arguments(self, parser: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
            parser.add_argument("--colour", default="red")

    assert entry_options(Legacy(), {"colour": "blue"}) == {"colour": "blue"}
    with pytest.raises(OptionError, match="unknown option 'size'"):
        entry_options(Legacy(), {"size": 3})


def test_help_lists_own_options_first_and_a_redefined_one_where_its_base_put_it() -> None:
    @dataclasses.dataclass(frozen=True)
    class Base(ExporterOptions):
        first: str | None = option(help="one")
        second: int | None = option(group="g", help="two")

    @dataclasses.dataclass(frozen=True)
    class Own(Base):
        mine: bool = option(False, help="mine")
        first: str | None = option(choices=("x",), help="one, redefined")

    assert [o.name for o in Own.schema()] == ["mine", "first", "second"]
    parser = _Parser(prog="p", add_help=False)
    Own.add_arguments(parser)
    text = parser.format_help().partition("options:")[2]
    assert text.index("--mine") < text.index("--first") < text.index("g:") < text.index("--second")
    assert Own.from_table({"first": "x", "second": "2"}) == Own(mine=False, first="x", second=2)

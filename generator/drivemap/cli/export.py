"""``drivemap export``: run an exporter plugin on one model (or several devices of one line)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from drivemap.cli.common import (
    Parser,
    UsageError,
    project_flags,
    project_of,
    report,
    write_change,
)
from drivemap.diagnostics import CompileError, Diagnostic, Location
from drivemap.frontend.project import display

if TYPE_CHECKING:
    pass


def cmd_export(args: argparse.Namespace) -> int:
    from drivemap.backends.exporters import OptionError, available
    from drivemap.backends.exporters.base import MultiDevice
    from drivemap.build import export_files
    from drivemap.compiler import compile_map, resolve_map

    exporters = available()
    if args.help:
        return _export_help(args, exporters)
    if args.list:
        width = max(len(n) for n in exporters)
        for name, cls in exporters.items():
            print(f"{name.ljust(width)}  {cls.help}")
        return 0
    if not args.model:
        raise UsageError("drivemap export", "give MODEL or PATH (or --list)")
    if args.format not in exporters:
        raise UsageError("drivemap export", f"unknown format {args.format!r} (installed: {', '.join(exporters)})")
    exporter = exporters[args.format]()
    own = _exporter_parser(args.format, exporter)
    hint = f" (its options: drivemap export --format {args.format} --help)"
    try:
        values = vars(own.parse_args(args.rest))
    except UsageError as exc:
        raise UsageError(f"drivemap export --format {args.format}", str(exc).split(": error: ", 1)[-1] + hint) from None
    project = project_of(args)
    devices = [(compile_map(resolve_map(name, project), [exporter]), unit) for name, unit in map(_device, args.model)]
    try:
        if len(devices) == 1:
            model, unit = devices[0]
            if unit is not None:
                if values.get("unit") is not None:
                    raise OptionError(f"the unit is given twice: {args.model[0]} and --unit {values['unit']}")
                values["unit"] = unit
            files = export_files(exporter, model, project, values, args.output)
        elif not (exporter.multi_device and isinstance(exporter, MultiDevice)):
            raise UsageError(f"drivemap export --format {args.format}", "several devices in one export: only "
                             "--format homeassistant (one hub per line); export them one by one")
        else:
            from drivemap.build import options_for

            files = exporter.render_line(devices, options_for(project, values))
    except OptionError as exc:
        raise UsageError(f"drivemap export --format {args.format}", str(exc) + hint) from None
    if args.output is None:
        for _, text in sorted(files.items()):
            _refuse_unencodable(text, devices[0][0].path)
        for _, text in sorted(files.items()):
            sys.stdout.write(text)
        return 0
    return _write_export(Path(args.output), files, exporter.multi_file, args.force)


def _device(text: str) -> tuple[str, int | None]:
    """``MODEL`` or ``MODEL:UNIT`` (a device on a line shared with others)."""
    name, sep, unit = text.rpartition(":")
    if sep and name and unit.isascii() and unit.isdigit():
        return name, int(unit)
    return text, None


def _exporter_parser(fmt: str, exporter: object) -> argparse.ArgumentParser:
    own = Parser(prog=f"drivemap export MODEL --format {fmt}", add_help=False)
    exporter.add_arguments(own)  # type: ignore[attr-defined]
    return own


def _export_help(args: argparse.Namespace, exporters: dict[str, Any]) -> int:
    """``drivemap export --help``; with ``--format X`` the options of that exporter too."""
    sys.stdout.write(args.help_parser.format_help())
    if args.format in exporters:
        own = _exporter_parser(args.format, exporters[args.format]())
        options = own.format_help().partition("\n\n")[2].strip("\n")  # without the usage lines
        print(f"\noptions of --format {args.format} ({exporters[args.format].help}):")
        print(options.replace("options:\n", "", 1) if options else "  (none)")
    else:
        print(f"\nunknown format {args.format!r}; installed: {', '.join(exporters)}")
    print("\n(each exporter has its own options: drivemap export --format NAME --help)")
    return 0


def _refuse_unencodable(text: str, source: str) -> None:
    """Output that UTF-8 cannot hold (a lone surrogate from the map) is refused before any is written."""
    try:
        text.encode("utf-8")
    except UnicodeEncodeError as exc:
        raise CompileError([Diagnostic(Location(display(source), 1, 1), f"the export cannot be written as UTF-8: "
                                       f"character U+{ord(text[exc.start]):04X} (a lone surrogate from the map) "
                                       f"at offset {exc.start}")]) from None


def _write_export(target: Path, files: dict[str, str], multi: bool, force: bool) -> int:
    from drivemap.backends import output

    if not multi:  # one file: written alone, no manifest or lock beside it
        errors = output.write_single(target, next(iter(files.values())), force=force)
        if errors:
            return report(errors)
        print(f"wrote {display(target)}")
        return 0
    root = target
    with output.locked([root]):
        change = output.plan(root, files, prune=False, force=force)
        if change.errors:
            return report(change.errors)
        write_change(change)
    print(f"wrote {display(target)}" + (f"/ ({len(files)} files)" if multi else ""))
    return 0


def export_parser(sub: Any) -> None:
    """``drivemap export``: its own ``--help`` also lists the chosen exporter's options."""
    s = sub.add_parser("export", help="export a model with an exporter plugin (--list shows them)", add_help=False)
    s.add_argument("-h", "--help", action="store_true",
                   help="show this help; with --format NAME the options of that exporter too")
    s.add_argument("model", nargs="*", metavar="MODEL[:UNIT]",
                   help="model id or map path; several MODEL:UNIT (ev:1 vfd1000:2) for devices sharing one line "
                        "(--format homeassistant: one hub)")
    s.add_argument("--format", default="json", help="exporter name (default: json)")
    s.add_argument("-o", "--output", default=None, metavar="FILE|DIR", help="write here instead of stdout")
    s.add_argument("--force", action="store_true", help="replace an output file changed since drivemap wrote it")
    s.add_argument("--list", action="store_true", help="list the installed exporters")
    project_flags(s)
    s.set_defaults(func=cmd_export, help_parser=s)



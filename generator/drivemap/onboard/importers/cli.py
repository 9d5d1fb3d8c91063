"""``drivemap import FORMAT FILE... [-o maps/ID.yaml] [--model ID] [--force]``: a map from definitions users own.

FORMAT is ``homeassistant`` (a ``modbus:`` YAML, exported or hand-written), ``esphome``
(``modbus_controller`` entities), ``sunspec`` (SunSpec model JSON files or model numbers, laid out from
``--base``; numbers need ``drivemap[sunspec]``), ``csv`` (drivemap's CSV export or a vendor sheet),
``json`` (drivemap's JSON export: the normalized model) or ``pymodbus-sim`` (a pymodbus simulator
configuration: its tables, addresses, cell types and values), ``evcc`` (an evcc meter or charger
template: its render block expanded per usage), ``ha-solarman`` (an ha-solarman inverter profile) or
``modbus-local-gateway`` (a modbus_local_gateway device config); these three mark the map
``evidence: imported`` with its origin (project, path, commit, licence) when SOURCE and LICENSE files
sit beside the file or above it.
The map validates as written; a fact the source does not state stays out (or null) and is listed in
the review printed after it. The map goes to ``-o`` or the project's maps folder as ``MODEL.yaml``,
never over an existing file unless ``--force``.
"""

from __future__ import annotations

import argparse
import datetime
import re
from pathlib import Path

from drivemap.diagnostics import CompileError, Diagnostic, Location
from drivemap.frontend.project import display, load_project
from drivemap.onboard.importers.mapdoc import MapDoc, model_id, snake, target_path, write_map

__all__ = ["FORMATS", "add_parser"]

FORMATS = ("homeassistant", "esphome", "sunspec", "csv", "json", "pymodbus-sim", "evcc", "ha-solarman",
           "modbus-local-gateway")
#: the formats that read one device definition per file (another project's)
_ONE_FILE = {"evcc": ("evcc", "import_evcc"), "ha-solarman": ("solarman", "import_solarman"),
             "modbus-local-gateway": ("mlg", "import_mlg")}


def add_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("import", help="a map from Home Assistant, ESPHome, SunSpec, CSV, JSON, pymodbus simulator, evcc, ha-solarman or modbus_local_gateway definitions",
                       description=__doc__.split("\n\n", 1)[1] if __doc__ else None,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("format", metavar="FORMAT", help=f"one of {', '.join(FORMATS)}")
    p.add_argument("files", nargs="+", metavar="FILE",
                   help="source files (sunspec: model JSON files or model numbers, N:L gives a model's length)")
    p.add_argument("-o", "--output", default=None, metavar="MAP.yaml",
                   help="where to write the map (default: the project's maps folder/MODEL.yaml)")
    p.add_argument("--model", default=None, metavar="ID", help="model id (default: from the source or -o)")
    p.add_argument("--force", action="store_true", help="replace an existing map file")
    p.add_argument("--base", type=int, default=40000, metavar="N", help="sunspec: address of 'SunS' (default 40000)")
    p.add_argument("--table", default=None, choices=["holding", "input", "coil", "discrete"],
                   help="csv: the table of a sheet that does not say it")
    p.add_argument("--word-order", default=None, choices=["high_first", "low_first"],
                   help="csv: word order of a sheet's 32/64-bit values when it does not say it")
    p.add_argument("--maps", action="append", default=None, metavar="PATH", help=argparse.SUPPRESS)
    p.set_defaults(func=cmd_import)


def cmd_import(args: argparse.Namespace) -> int:
    from drivemap.onboard.importers.sunspec import SunSpecError

    if args.format not in FORMATS:
        from drivemap.device.target import locate_error

        raise locate_error(args.format, f"unknown format {args.format!r} (one of {', '.join(FORMATS)})")
    paths = [Path(f) for f in args.files]
    if args.format != "sunspec":
        for path in paths:
            if not path.is_file():
                raise CompileError([Diagnostic(Location(display(path), 1, 1), "no such file")])
    names = ", ".join(p.name for p in paths)
    doc = MapDoc("imported", f"Imported from {names}", f"{args.format} import {datetime.date.today().isoformat()}",
                 names)
    try:
        suggested = _run(args, doc, paths)
    except SunSpecError as exc:
        from drivemap.device.target import locate_error

        raise locate_error(args.files[0], str(exc)) from None
    except (ValueError, TypeError, KeyError, AttributeError, IndexError, OverflowError, RecursionError) as exc:
        # an entry of a shape no importer rule reads (a list where a number belongs ...): nothing is written
        where = paths[0] if paths[0].is_file() else Path(args.files[0])
        raise CompileError([Diagnostic(Location(display(where), 1, 1),
                                       f"cannot import an entry of this file: {type(exc).__name__}: {exc}")]) from None
    if not doc.registers:
        raise CompileError([Diagnostic(Location(display(paths[0]), 1, 1),
                                       "no registers found to import" + _skipped(doc))])
    doc.model = model_id(args.model, args.output, suggested or snake(re.sub(r"\..*$", "", paths[0].name), "device"))
    target = target_path(args.output, doc.model, _maps_folder(args))
    write_map(doc, target, force=args.force)
    _summary(doc, target)
    return 0


def _maps_folder(args: argparse.Namespace) -> Path:
    return load_project(maps=args.maps).maps_folder()


def _skipped(doc: MapDoc) -> str:
    return f" ({'; '.join(doc.review.skipped[:3])})" if doc.review.skipped else ""


def _run(args: argparse.Namespace, doc: MapDoc, paths: list[Path]) -> str | None:
    """Fill ``doc`` from the sources; the model id they suggest (None: none)."""
    if args.format == "csv":
        from drivemap.onboard.importers.csvfile import import_csv

        for path in paths:
            import_csv(doc, path, args.table, args.word_order)
        return None
    if args.format == "sunspec":
        from drivemap.onboard.importers.sunspec_files import import_sunspec

        import_sunspec(doc, args.files, args.base)
        return None
    if args.format == "json":
        from drivemap.onboard.importers.modeljson import import_model_json

        return import_model_json(doc, paths[0]) if _one(paths) else None
    if args.format == "pymodbus-sim":
        from drivemap.onboard.importers.pymodbus_sim import import_pymodbus_sim

        return import_pymodbus_sim(doc, paths[0]) if _one(paths) else None
    if args.format in _ONE_FILE:
        import importlib

        module, func = _ONE_FILE[args.format]
        reader = getattr(importlib.import_module(f"drivemap.onboard.importers.{module}"), func)
        return str(reader(doc, paths[0])) if _one(paths) else None
    if args.format == "homeassistant":
        from drivemap.onboard.importers.homeassistant import import_homeassistant

        return import_homeassistant(doc, paths)
    from drivemap.onboard.importers.esphome import import_esphome

    return import_esphome(doc, paths)


def _one(paths: list[Path]) -> bool:
    """A json or pymodbus-sim import reads one file (one device)."""
    if len(paths) > 1:
        raise CompileError([Diagnostic(Location(display(paths[1]), 1, 1),
                                       "one file per import for this format (it describes one device)")])
    return True


def _summary(doc: MapDoc, target: Path) -> None:
    shown = display(target)
    enums = len(doc.enums)
    print(f"wrote {shown}: {len(doc.registers)} registers, {enums} enum{'' if enums == 1 else 's'}")
    lines = doc.review.lines()
    if lines:
        print("review (not stated by the source, or left out):")
        for line in lines:
            print(line)
    if doc.protocol is None:
        print("the protocol section (unit ids, serial line, timing, exceptions) is null where the source is silent")
    print(f"next: drivemap validate {shown}; drivemap verify {doc.model} --tcp HOST (against the device)")

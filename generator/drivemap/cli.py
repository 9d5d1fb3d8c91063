"""The ``drivemap`` command: validate | build | check | examples | export | new | simulate | schema |
gateway, and at the drive (:mod:`drivemap.live`): read | write | watch | scan | verify.

Every verb acts on the project of the working directory (:mod:`drivemap.frontend.project`); explicit paths
and flags win over its ``[tool.drivemap]`` settings. Every bad input ends in ``path:line:col:
error: ...`` lines and exit status 1, never a traceback.
"""

from __future__ import annotations

import argparse
import os
import re
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

from drivemap import __version__
from drivemap.diagnostics import CompileError, Diagnostic, Location
from drivemap.frontend.project import Project, display, load_project
from drivemap.model.nodes import Model

if TYPE_CHECKING:
    from drivemap.backends.exporters.base import Exporter
    from drivemap.backends.output import Change


class UsageError(Exception):
    """A bad command line: printed as ``drivemap VERB: error: ...`` with exit status 1."""

    def __init__(self, prog: str, message: str) -> None:
        super().__init__(f"{prog}: error: {message}")


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        raise UsageError(self.prog, message)


def _project(args: argparse.Namespace, maps: Sequence[str] | None = None) -> Project:
    return load_project(
        maps=maps or getattr(args, "maps", None),
        out=getattr(args, "out", None),
        package=getattr(args, "package", None),
        docs=getattr(args, "docs", None),
        behaviours=getattr(args, "behaviours", None),
    )


def _compile(files: Sequence[Path], exporters: Sequence[Exporter] | None = None) -> tuple[list[Model], list[Diagnostic]]:
    """Compile every map with the checks of ``exporters`` (None: the ones ``build`` writes)."""
    from drivemap.compiler import compile_map

    models: list[Model] = []
    errors: list[Diagnostic] = []
    for path in files:
        try:
            models.append(compile_map(path, exporters))
        except CompileError as exc:
            errors.extend(exc.diagnostics)
    first: dict[str, Model] = {}
    for model in models:
        if model.name in first:
            errors.append(Diagnostic(Location(model.path, _model_line(model.path), 1),
                                     f"model id {model.name!r} is also the id of {first[model.name].path}: "
                                     "one map per model (the generated package would come from one of them)",
                                     related=((Location(first[model.name].path, 1, 1), "the other map"),)))
        first.setdefault(model.name, model)
    return models, errors


def _model_line(path: str) -> int:
    try:
        lines = Path(path).read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError):
        return 1
    return next((n for n, line in enumerate(lines, 1) if line.strip().startswith("model:")), 1)


def _project_models(project: Project, exporters: Sequence[Exporter] | None = None) -> list[Model]:
    files = project.map_files()
    if not files:
        where = ", ".join(display(m) for m in project.maps)
        raise CompileError([Diagnostic(Location(where, 1, 1), "no maps found (run `drivemap new MODEL`, or set maps)")])
    models, errors = _compile(files, exporters)
    if errors:
        raise CompileError(errors)
    return models


def _report(errors: Sequence[Diagnostic]) -> int:
    for d in errors:
        print(d.format(), file=sys.stderr)
    if errors:
        count = len(errors)
        print(f"{count} error{'s' if count != 1 else ''}", file=sys.stderr)
        return 1
    return 0


def _summary(model: Model) -> str:
    counts = model.status_counts()
    cells = sum(r.count for r in model.registers)
    return (
        f"{model.name}: {len(model.registers)} registers ({cells} with array elements), "
        f"{len(model.enums)} enums, {len(model.examples)} examples "
        f"({counts['verified']} verified, {counts['erratum']} errata, {counts['illegible']} illegible)"
    )


# ---------------------------------------------------------------- validate, build, check


def cmd_validate(args: argparse.Namespace) -> int:
    project = _project(args, args.paths)
    models = _project_models(project, _checking_exporters(args.exporter or []))
    for m in models:
        print(f"{m.path}: ok ({_summary(m)})")
    return 0


def _checking_exporters(names: Sequence[str]) -> list[Exporter]:
    """The exporters whose ``validate`` hooks ``drivemap validate --exporter`` runs (none: the front end only)."""
    if not names:
        return []
    from drivemap.backends.exporters import available, load

    if "all" in names:
        found = available()
        names = ["python", "docs", *(n for n in found if n not in ("python", "docs"))]
        return [found[n]() for n in names]
    chosen = {n: load(n) for n in dict.fromkeys(names)}
    unknown = [n for n, cls in chosen.items() if cls is None]
    if unknown:
        raise UsageError("drivemap validate", f"unknown exporter {unknown[0]!r} (installed: "
                                              f"{', '.join(available())}; or all)")
    return [cls() for cls in chosen.values() if cls is not None]


def cmd_build(args: argparse.Namespace) -> int:
    from drivemap.backends import output
    from drivemap.build import outputs_by_root

    project = _project(args, args.paths)
    models = _project_models(project)
    grouped = outputs_by_root(project, models)
    with output.locked(grouped):  # one build per output folder at a time; planned and written under it
        changes = [output.plan(root, files, prune=prune, force=args.force) for root, (files, prune) in grouped.items()]
        errors = [e for c in changes for e in c.errors]
        if errors:
            return _report(errors)
        for change in changes:
            _write_change(change)
    for m in models:
        print(_summary(m))
    for change in changes:
        line = f"{display(change.root)}/: {len(change.files)} files ({len(change.write)} written, {len(change.delete)} deleted)"
        print(line)
        for rel in change.edited:
            print(f"  replaced {display(change.root / rel)}: it had been edited by hand (generated files are not "
                  "edited; change the map or the templates)")
        for rel in change.kept:
            print(f"  kept {display(change.root / rel)}: edited by hand (no map produces it any more; not deleted, "
                  "no longer tracked)")
    return 0


def _write_change(change: Change) -> None:
    """Carry out a planned change; a folder or file the system refuses is a located error."""
    from drivemap.backends import output

    try:
        output.write(change)
    except OSError as exc:
        where = display(change.root)
        raise CompileError([Diagnostic(Location(where, 1, 1), f"cannot write the output here: "
                                                              f"{exc.strerror or exc}")]) from None


def cmd_check(args: argparse.Namespace) -> int:
    from drivemap.backends import output
    from drivemap.build import outputs_by_root

    project = _project(args, args.paths)
    models = _project_models(project)
    stale = [(root / rel, why) for root, (files, _) in outputs_by_root(project, models).items()
             for rel, why in output.check(root, files)]
    if stale:
        print("generated output is stale; run `drivemap build`. Differing files:", file=sys.stderr)
        for path, why in stale:
            print(f"  {display(path)}: {why}", file=sys.stderr)
        return 1
    print(f"{display(project.out)}/ is up to date ({len(models)} models)")
    return 0


# ---------------------------------------------------------------- examples, export


def cmd_examples(args: argparse.Namespace) -> int:
    from drivemap.compiler import compile_map, resolve_map

    project = _project(args)
    models = [compile_map(resolve_map(args.model, project))] if args.model else _project_models(project)
    header = ("model", "example", "mode", "source", "status")
    rows = [(m.name, ex.name, ex.mode, ex.source, ex.status) for m in models for ex in m.examples]
    widths = [max(len(str(r[i])) for r in [*rows, header]) for i in range(5)]
    print("  ".join(h.ljust(w) for h, w in zip(header, widths, strict=True)))
    for row in rows:
        print("  ".join(str(c).ljust(w) for c, w in zip(row, widths, strict=True)).rstrip())
    print()
    for m in models:
        c = m.status_counts()
        print(f"{m.name}: frames {len(m.examples)}, verified {c['verified']}, errata {c['erratum']}, illegible {c['illegible']}")
    return 0


def cmd_export(args: argparse.Namespace) -> int:
    from drivemap.backends.exporters import OptionError, available
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
    project = _project(args)
    devices = [(compile_map(resolve_map(name, project)), unit) for name, unit in map(_device, args.model)]
    try:
        if len(devices) == 1:
            model, unit = devices[0]
            if unit is not None:
                if values.get("unit") is not None:
                    raise OptionError(f"the unit is given twice: {args.model[0]} and --unit {values['unit']}")
                values["unit"] = unit
            files = export_files(exporter, model, project, values, args.output)
        elif not hasattr(exporter, "render_line"):
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
    own = _Parser(prog=f"drivemap export MODEL --format {fmt}", add_help=False)
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
            return _report(errors)
        print(f"wrote {display(target)}")
        return 0
    root = target
    with output.locked([root]):
        change = output.plan(root, files, prune=False, force=force)
        if change.errors:
            return _report(change.errors)
        _write_change(change)
    print(f"wrote {display(target)}" + (f"/ ({len(files)} files)" if multi else ""))
    return 0


# ---------------------------------------------------------------- new, schema, simulate


def cmd_new(args: argparse.Namespace) -> int:
    from drivemap.backends.render import scaffold
    from drivemap.compiler import compile_text
    from drivemap.frontend.schema import SCHEMA_PATH

    folder = Path(args.dir) if args.dir else _project(args).maps_folder()
    if not re.fullmatch(r"[a-z][a-z0-9_]{0,63}", args.model):
        raise CompileError([Diagnostic(Location(display(folder / f"{args.model[:80]}.yaml"), 1, 1),
                                       f"model id {args.model[:80]!r} must be a lower-case identifier of at most "
                                       "64 characters")])
    target = folder / f"{args.model}.yaml"
    where = Location(display(target), 1, 1)
    if os.path.lexists(target):
        raise CompileError([Diagnostic(where, "file exists; not overwritten")])
    ref = Path(os.path.relpath(SCHEMA_PATH.resolve(), folder.resolve())).as_posix()
    text = scaffold(args.model, ref)
    try:
        compile_text(text, display(target))  # never write a map that validate refuses (a keyword id, ...)
    except CompileError as exc:
        problems = "; ".join(d.message for d in exc.diagnostics)
        raise CompileError([Diagnostic(where, f"model id {args.model!r} cannot be used: {problems}")]) from None
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with open(target, "x", encoding="utf-8", newline="\n") as handle:
            handle.write(text)
    except OSError as exc:
        raise CompileError([Diagnostic(where, f"cannot write the map: {exc.strerror or exc}")]) from None
    print(f"wrote {display(target)}")
    return 0


def cmd_migrate(args: argparse.Namespace) -> int:
    from drivemap.migrate import run

    project = _project(args, args.paths)
    return run(project.map_files(), args.write)


def cmd_schema(args: argparse.Namespace) -> int:
    from drivemap.frontend.schema import SCHEMA_PATH

    if args.print:
        sys.stdout.write(SCHEMA_PATH.read_text(encoding="utf-8"))
    else:
        print(SCHEMA_PATH.resolve())
    return 0


def cmd_simulate(args: argparse.Namespace) -> int:
    from drivemap.build import simulator_factory
    from drivemap.compiler import compile_map, resolve_map
    from drivemap.runtime.sim.cli import serve_cli

    project = _project(args)
    model = compile_map(resolve_map(args.model, project))
    args.factory = simulator_factory(model, project)
    code: int = serve_cli(args)
    return code


def cmd_gateway(args: argparse.Namespace) -> int:
    from drivemap.gateway.cli import run_cli

    return run_cli(args, _project(args))


# ---------------------------------------------------------------- the parser


def _project_flags(p: argparse.ArgumentParser, *, out: bool = True) -> None:
    g = p.add_argument_group("project settings (override [tool.drivemap])")
    if out:
        g.add_argument("--out", default=None, help="the generated package's folder")
        g.add_argument("--package", default=None, help="the generated package's import name")
        g.add_argument("--docs", default=None, help="the generated docs' folder")
    g.add_argument("--maps", action="append", default=None, metavar="PATH", help="map file or folder (repeatable)")
    g.add_argument("--behaviours", action="append", default=None, metavar="MODULE",
                   help="module that registers simulator behaviours (repeatable)")


def parser() -> argparse.ArgumentParser:
    p = _Parser(prog="drivemap", description="Register-map compiler for Modbus drives.")
    p.add_argument("--version", action="version", version=f"drivemap {__version__}")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)
    s = sub.add_parser("validate", help="validate maps (default: the project's maps)",
                       description="Check maps: the schema and the semantic checks of the map language. The "
                                   "exporters' own checks (the generated Python names, the docs anchors) run where "
                                   "an exporter writes (build, check, export) or here with --exporter.")
    s.add_argument("paths", nargs="*", metavar="PATH", help="map files or folders")
    s.add_argument("--exporter", action="append", default=None, metavar="NAME",
                   help="also run this exporter's checks (repeatable; `all`: every installed exporter, "
                        "`python` and `docs`: what build writes)")
    _project_flags(s, out=False)
    s.set_defaults(func=cmd_validate)
    for name, func, text in (("build", cmd_build, "validate, verify examples, write the generated package and docs"),
                             ("check", cmd_check, "exit 1 if the generated output differs from what build would write")):
        s = sub.add_parser(name, help=text)
        s.add_argument("paths", nargs="*", metavar="PATH", help="map files or folders (default: the project's maps)")
        if name == "build":
            s.add_argument("--force", action="store_true",
                           help="build into a non-empty folder without a manifest; replace files changed by hand")
        _project_flags(s)
        s.set_defaults(func=func)
    s = sub.add_parser("examples", help="verify every example frame and print a table")
    s.add_argument("model", nargs="?", metavar="MODEL|PATH")
    _project_flags(s, out=False)
    s.set_defaults(func=cmd_examples)
    _export_parser(sub)
    s = sub.add_parser("new", help="scaffold MODEL.yaml in the project's maps folder")
    s.add_argument("model")
    s.add_argument("--dir", default=None, help="folder for the new map (default: the project's maps folder)")
    _project_flags(s, out=False)
    s.set_defaults(func=cmd_new)
    s = sub.add_parser("migrate", help="rewrite maps of an older format to the current one (a diff; --write applies)")
    s.add_argument("paths", nargs="*", metavar="PATH", help="map files or folders (default: the project's maps)")
    s.add_argument("--write", action="store_true", help="write the migrated maps (default: print the diff only)")
    _project_flags(s, out=False)
    s.set_defaults(func=cmd_migrate)
    s = sub.add_parser("schema", help="print the path of the installed map schema (--print: its content)")
    s.add_argument("--print", action="store_true")
    s.set_defaults(func=cmd_schema)
    s = sub.add_parser("simulate", help="serve a model's simulator (a map path is compiled in memory)")
    from drivemap.runtime.sim.cli import add_arguments

    add_arguments(s, with_model=True)
    _project_flags(s, out=False)
    s.set_defaults(func=cmd_simulate)
    from drivemap.live import add_parsers

    add_parsers(sub)  # read, write, watch, scan, verify: a live device by name
    from drivemap.onboard.draft.cli import add_parser as draft_parser

    draft_parser(sub)  # draft: a map from the register tables of a manual
    from drivemap.onboard.importers.cli import add_parser as import_parser
    from drivemap.onboard.probe_cli import add_parser as probe_parser

    import_parser(sub)  # import: Home Assistant, ESPHome, SunSpec, CSV definitions -> a map
    probe_parser(sub)  # probe: what a live device answers, as a skeleton map
    s = sub.add_parser("gateway", help="publish buses of drives to MQTT (Home Assistant discovery) and OPC UA")
    from drivemap.gateway.cli import add_arguments as gateway_arguments

    gateway_arguments(s)
    _project_flags(s, out=False)
    s.set_defaults(func=cmd_gateway)
    return p


def _export_parser(sub: Any) -> None:
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
    _project_flags(s)
    s.set_defaults(func=cmd_export, help_parser=s)


def main(argv: Sequence[str] | None = None) -> int:
    try:
        args, rest = parser().parse_known_args(argv)
        if rest and args.command != "export" and not getattr(args, "takes_rest", False):
            raise UsageError(f"drivemap {args.command}", f"unrecognized arguments: {' '.join(rest)}")
        args.rest = rest
        result: int = args.func(args)
        return result
    except UsageError as exc:
        print(f"{exc}\n(see `drivemap --help`)", file=sys.stderr)
        return 1
    except CompileError as exc:
        return _report(exc.diagnostics)
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        return 0
    except OSError as exc:  # a path the system refuses that no verb located itself: still no traceback
        where = display(os.fsdecode(exc.filename)) if exc.filename else "drivemap"
        print(f"{where}:1:1: error: {exc.strerror or exc}", file=sys.stderr)
        print("1 error", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())

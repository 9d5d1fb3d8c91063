"""The ``drivemap`` command: validate | build | check | examples | export | new | simulate | schema |
gateway, and at the drive (:mod:`drivemap.live`): read | write | watch | scan | verify.

Every verb acts on the project of the working directory (:mod:`drivemap.project`); explicit paths
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
from typing import NoReturn

from . import __version__
from .diagnostics import CompileError, Diagnostic, Location
from .model import Model
from .project import Project, display, load_project


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


def _compile(files: Sequence[Path]) -> tuple[list[Model], list[Diagnostic]]:
    from .compiler import compile_map

    models: list[Model] = []
    errors: list[Diagnostic] = []
    for path in files:
        try:
            models.append(compile_map(path))
        except CompileError as exc:
            errors.extend(exc.diagnostics)
    return models, errors


def _project_models(project: Project) -> list[Model]:
    files = project.map_files()
    if not files:
        where = ", ".join(display(m) for m in project.maps)
        raise CompileError([Diagnostic(Location(where, 1, 1), "no maps found (run `drivemap new MODEL`, or set maps)")])
    models, errors = _compile(files)
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
    models = _project_models(project)
    for m in models:
        print(f"{m.path}: ok ({_summary(m)})")
    return 0


def cmd_build(args: argparse.Namespace) -> int:
    from . import output
    from .build import outputs_by_root

    project = _project(args, args.paths)
    models = _project_models(project)
    changes = [output.plan(root, files, prune=prune, force=args.force)
               for root, (files, prune) in outputs_by_root(project, models).items()]
    errors = [e for c in changes for e in c.errors]
    if errors:
        return _report(errors)
    for change in changes:
        output.write(change)
    for m in models:
        print(_summary(m))
    for change in changes:
        line = f"{display(change.root)}/: {len(change.files)} files ({len(change.write)} written, {len(change.delete)} deleted)"
        print(line)
        for rel in change.edited:
            print(f"  replaced {display(change.root / rel)}: it had been edited by hand (generated files are not "
                  "edited; change the map or the templates)")
    return 0


def cmd_check(args: argparse.Namespace) -> int:
    from . import output
    from .build import outputs_by_root

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
    from .compiler import compile_map, resolve_map

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
    from .build import export_files
    from .compiler import compile_map, resolve_map
    from .exporters import OptionError, available

    exporters = available()
    if args.list:
        width = max(len(n) for n in exporters)
        for name, cls in exporters.items():
            print(f"{name.ljust(width)}  {cls.help}")
        return 0
    if args.model is None:
        raise UsageError("drivemap export", "give MODEL or PATH (or --list)")
    if args.format not in exporters:
        raise UsageError("drivemap export", f"unknown format {args.format!r} (installed: {', '.join(exporters)})")
    exporter = exporters[args.format]()
    own = _Parser(prog=f"drivemap export MODEL --format {args.format}", add_help=False)
    exporter.add_arguments(own)
    values = vars(own.parse_args(args.rest))
    project = _project(args)
    model = compile_map(resolve_map(args.model, project))
    try:
        files = export_files(exporter, model, project, values, args.output)
    except OptionError as exc:
        raise UsageError(f"drivemap export --format {args.format}", str(exc)) from None
    if args.output is None:
        for _, text in sorted(files.items()):
            sys.stdout.write(text)
        return 0
    return _write_export(Path(args.output), files, exporter.multi_file, args.force)


def _write_export(target: Path, files: dict[str, str], multi: bool, force: bool) -> int:
    from . import output

    root = target if multi else target.parent
    change = output.plan(root, files if multi else {target.name: next(iter(files.values()))}, prune=False, force=force)
    if change.errors:
        return _report(change.errors)
    output.write(change)
    print(f"wrote {display(target)}" + (f"/ ({len(files)} files)" if multi else ""))
    return 0


# ---------------------------------------------------------------- new, schema, simulate


def cmd_new(args: argparse.Namespace) -> int:
    from .render import scaffold
    from .schema import SCHEMA_PATH

    folder = Path(args.dir) if args.dir else _project(args).maps_folder()
    target = folder / f"{args.model}.yaml"
    if not re.fullmatch(r"[a-z][a-z0-9_]*", args.model):
        raise CompileError([Diagnostic(Location(display(target), 1, 1),
                                       f"model id {args.model!r} must be a lower-case identifier")])
    if os.path.lexists(target):
        raise CompileError([Diagnostic(Location(display(target), 1, 1), "file exists; not overwritten")])
    folder.mkdir(parents=True, exist_ok=True)
    ref = Path(os.path.relpath(SCHEMA_PATH.resolve(), folder.resolve())).as_posix()
    with open(target, "x", encoding="utf-8", newline="\n") as handle:
        handle.write(scaffold(args.model, ref))
    print(f"wrote {display(target)}")
    return 0


def cmd_schema(args: argparse.Namespace) -> int:
    from .schema import SCHEMA_PATH

    if args.print:
        sys.stdout.write(SCHEMA_PATH.read_text(encoding="utf-8"))
    else:
        print(SCHEMA_PATH.resolve())
    return 0


def cmd_simulate(args: argparse.Namespace) -> int:
    from .build import simulator_factory
    from .compiler import compile_map, resolve_map
    from .runtime.simcli import serve_cli

    project = _project(args)
    model = compile_map(resolve_map(args.model, project))
    args.factory = simulator_factory(model, project)
    code: int = serve_cli(args)
    return code


def cmd_gateway(args: argparse.Namespace) -> int:
    from .gateway.cli import run_cli

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
    s = sub.add_parser("validate", help="validate maps (default: the project's maps)")
    s.add_argument("paths", nargs="*", metavar="PATH", help="map files or folders")
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
    s = sub.add_parser("export", help="export a model with an exporter plugin (--list shows them)")
    s.add_argument("model", nargs="?", metavar="MODEL|PATH")
    s.add_argument("--format", default="json", help="exporter name (default: json)")
    s.add_argument("-o", "--output", default=None, metavar="FILE|DIR", help="write here instead of stdout")
    s.add_argument("--force", action="store_true", help="replace an output file changed since drivemap wrote it")
    s.add_argument("--list", action="store_true", help="list the installed exporters")
    _project_flags(s)
    s.set_defaults(func=cmd_export)
    s = sub.add_parser("new", help="scaffold MODEL.yaml in the project's maps folder")
    s.add_argument("model")
    s.add_argument("--dir", default=None, help="folder for the new map (default: the project's maps folder)")
    _project_flags(s, out=False)
    s.set_defaults(func=cmd_new)
    s = sub.add_parser("schema", help="print the path of the installed map schema (--print: its content)")
    s.add_argument("--print", action="store_true")
    s.set_defaults(func=cmd_schema)
    s = sub.add_parser("simulate", help="serve a model's simulator (a map path is compiled in memory)")
    from .runtime.simcli import add_arguments

    add_arguments(s, with_model=True)
    _project_flags(s, out=False)
    s.set_defaults(func=cmd_simulate)
    from .live import add_parsers

    add_parsers(sub)  # read, write, watch, scan, verify: a live device by name
    from .onboard.importers.cli import add_parser as import_parser
    from .onboard.probe_cli import add_parser as probe_parser

    import_parser(sub)  # import: Home Assistant, ESPHome, SunSpec, CSV definitions -> a map
    probe_parser(sub)  # probe: what a live device answers, as a skeleton map
    s = sub.add_parser("gateway", help="publish buses of drives to MQTT (Home Assistant discovery) and OPC UA")
    from .gateway.cli import add_arguments as gateway_arguments

    gateway_arguments(s)
    _project_flags(s, out=False)
    s.set_defaults(func=cmd_gateway)
    return p


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


if __name__ == "__main__":
    sys.exit(main())

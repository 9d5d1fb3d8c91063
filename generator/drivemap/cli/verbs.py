"""The project verbs: validate, build, check, examples, new, migrate, schema, simulate, gateway."""

from __future__ import annotations

import argparse
import os
import re
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from drivemap.cli.common import (
    UsageError,
    compile_files,
    project_flags,
    project_models,
    project_of,
    report,
    summary,
    write_change,
)
from drivemap.diagnostics import CompileError, Diagnostic, Location
from drivemap.frontend.project import display

if TYPE_CHECKING:
    from drivemap.backends.exporters.base import Exporter


def cmd_validate(args: argparse.Namespace) -> int:
    from drivemap.compiler import looks_like_path, resolve_map

    checks = _checking_exporters(args.exporter or [])
    ids = [p for p in args.paths if not Path(p).exists() and not looks_like_path(p)]
    if ids:  # model ids: the project's map of that id, else the shipped or catalogue one (as export and read do)
        project = project_of(args)
        files = [resolve_map(name, project) for name in ids]
        paths = [p for p in args.paths if p not in ids]
        if paths:
            files += project_of(args, paths).map_files()
        models, errors = compile_files(list(dict.fromkeys(files)), checks)
        if errors:
            raise CompileError(errors)
    else:
        models = project_models(project_of(args, args.paths), checks)
    for m in models:
        print(f"{m.path}: ok ({summary(m)})")
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
    from drivemap.build import build_checks, outputs_cached, settled

    project = project_of(args, args.paths)
    models = project_models(project, build_checks())
    grouped = outputs_cached(project, models)
    changes = [output.plan(root, files, prune=prune, force=args.force) for root, (files, prune) in grouped.items()
               if root.is_dir()]
    if len(changes) < len(grouped) or not settled(changes):  # else nothing to do: no lock, no file touched
        with output.locked(grouped):  # one build per output folder at a time; planned and written under it
            changes = [output.plan(root, files, prune=prune, force=args.force)
                       for root, (files, prune) in grouped.items()]
            errors = [e for c in changes for e in c.errors]
            if errors:
                return report(errors)
            for change in changes:
                write_change(change)
    for m in models:
        print(summary(m))
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


def cmd_check(args: argparse.Namespace) -> int:
    from drivemap.backends import output
    from drivemap.build import build_checks, outputs_cached

    project = project_of(args, args.paths)
    models = project_models(project, build_checks())
    stale = [(root / rel, why) for root, (files, _) in outputs_cached(project, models).items()
             for rel, why in output.check(root, files)]
    if stale:
        print("generated output is stale; run `drivemap build`. Differing files:", file=sys.stderr)
        for path, why in stale:
            print(f"  {display(path)}: {why}", file=sys.stderr)
        return 1
    print(f"{display(project.out)}/ is up to date ({len(models)} models)")
    return 0


def cmd_examples(args: argparse.Namespace) -> int:
    from drivemap.compiler import compile_map, resolve_map

    project = project_of(args)
    models = [compile_map(resolve_map(args.model, project))] if args.model else project_models(project)
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


def cmd_new(args: argparse.Namespace) -> int:
    from drivemap.backends.render import scaffold
    from drivemap.compiler import compile_text
    from drivemap.frontend.schema import SCHEMA_PATH

    folder = Path(args.dir) if args.dir else project_of(args).maps_folder()
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
        from drivemap.build import build_checks

        compile_text(text, display(target), build_checks())  # never write a map that build refuses (id index, ...)
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

    project = project_of(args, args.paths)
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

    project = project_of(args)
    model = compile_map(resolve_map(args.model, project))
    args.factory = simulator_factory(model, project)
    code: int = serve_cli(args)
    return code


def cmd_gateway(args: argparse.Namespace) -> int:
    from drivemap.gateway.cli import run_cli

    return run_cli(args, project_of(args))




def check_parsers(sub: Any) -> None:
    """validate, build, check, examples."""
    s = sub.add_parser("validate", help="validate maps (default: the project's maps)",
                       description="Check maps: the schema and the semantic checks of the map language. The "
                                   "exporters' own checks (the generated Python names, the docs anchors) run where "
                                   "an exporter writes (build, check, export) or here with --exporter.")
    s.add_argument("paths", nargs="*", metavar="PATH|MODEL",
                   help="map files or folders, or model ids (the project's map, else the shipped or catalogue map)")
    s.add_argument("--exporter", action="append", default=None, metavar="NAME",
                   help="also run this exporter's checks (repeatable; `all`: every installed exporter, "
                        "`python` and `docs`: what build writes)")
    project_flags(s, out=False)
    s.set_defaults(func=cmd_validate)
    for name, func, text in (("build", cmd_build, "validate, verify examples, write the generated package and docs"),
                             ("check", cmd_check, "exit 1 if the generated output differs from what build would write")):
        s = sub.add_parser(name, help=text)
        s.add_argument("paths", nargs="*", metavar="PATH", help="map files or folders (default: the project's maps)")
        if name == "build":
            s.add_argument("--force", action="store_true",
                           help="build into a non-empty folder without a manifest; replace files changed by hand")
        project_flags(s)
        s.set_defaults(func=func)
    s = sub.add_parser("examples", help="verify every example frame and print a table")
    s.add_argument("model", nargs="?", metavar="MODEL|PATH")
    project_flags(s, out=False)
    s.set_defaults(func=cmd_examples)


def other_parsers(sub: Any) -> None:
    """new, migrate, schema, simulate."""
    s = sub.add_parser("new", help="scaffold MODEL.yaml in the project's maps folder")
    s.add_argument("model")
    s.add_argument("--dir", default=None, help="folder for the new map (default: the project's maps folder)")
    project_flags(s, out=False)
    s.set_defaults(func=cmd_new)
    s = sub.add_parser("migrate", help="rewrite maps of an older format to the current one (a diff; --write applies)")
    s.add_argument("paths", nargs="*", metavar="PATH", help="map files or folders (default: the project's maps)")
    s.add_argument("--write", action="store_true", help="write the migrated maps (default: print the diff only)")
    project_flags(s, out=False)
    s.set_defaults(func=cmd_migrate)
    s = sub.add_parser("schema", help="print the path of the installed map schema (--print: its content)")
    s.add_argument("--print", action="store_true")
    s.set_defaults(func=cmd_schema)
    s = sub.add_parser("simulate", help="serve a model's simulator (a map path is compiled in memory)")
    from drivemap.runtime.sim.cli import add_arguments

    add_arguments(s, with_model=True)
    project_flags(s, out=False)
    s.set_defaults(func=cmd_simulate)


def gateway_parser(sub: Any) -> None:
    s = sub.add_parser("gateway", help="publish buses of drives to MQTT (Home Assistant discovery) and OPC UA")
    from drivemap.gateway.cli import add_arguments as gateway_arguments

    gateway_arguments(s)
    project_flags(s, out=False)
    s.set_defaults(func=cmd_gateway)

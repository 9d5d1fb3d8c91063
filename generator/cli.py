"""The ``drivemap`` command: validate | build | check | examples | export | new | simulate."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

from .diagnostics import CompileError, Diagnostic, Location
from .model import Model


def _compile_all(paths: Sequence[str]) -> tuple[list[Model], list[Diagnostic]]:
    from .compiler import compile_map, map_paths

    files = [Path(p) for p in paths] if paths else map_paths()
    models: list[Model] = []
    errors: list[Diagnostic] = []
    if not files:
        errors.append(Diagnostic(Location("maps", 1, 1), "no maps found"))
    for path in files:
        try:
            models.append(compile_map(path))
        except CompileError as exc:
            errors.extend(exc.diagnostics)
    return models, errors


def _report(errors: list[Diagnostic]) -> int:
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


def cmd_validate(args: argparse.Namespace) -> int:
    models, errors = _compile_all(args.paths)
    if not errors:
        for m in models:
            print(f"{m.path}: ok ({_summary(m)})")
    return _report(errors)


def cmd_build(args: argparse.Namespace) -> int:
    from .render import render_all, write_outputs

    models, errors = _compile_all([])
    if errors:
        return _report(errors)
    outputs = render_all(models)
    changed = write_outputs(outputs, Path(args.out))
    for m in models:
        print(_summary(m))
    print(f"wrote {len(outputs)} files to {args.out}/ ({changed} changed)")
    return 0


def cmd_check(args: argparse.Namespace) -> int:
    from .render import render_all, stale_files

    models, errors = _compile_all([])
    if errors:
        return _report(errors)
    stale = stale_files(render_all(models), Path(args.out))
    if stale:
        print(f"{args.out}/ is stale; run `drivemap build`. Differing files:", file=sys.stderr)
        for name, why in stale:
            print(f"  {args.out}/{name}: {why}", file=sys.stderr)
        return 1
    print(f"{args.out}/ is up to date ({len(models)} models)")
    return 0


def cmd_examples(args: argparse.Namespace) -> int:
    from .compiler import find_map, map_paths

    paths: list[str] = []
    if args.model:
        try:
            paths = [str(find_map(args.model))]
        except CompileError as exc:
            return _report(exc.diagnostics)
    models, errors = _compile_all(paths or [str(p) for p in map_paths()])
    if errors:
        return _report(errors)
    rows = [(m.name, ex.name, ex.mode, ex.source, ex.status) for m in models for ex in m.examples]
    widths = [max(len(str(r[i])) for r in rows + [("model", "example", "mode", "source", "status")]) for i in range(5)]
    header = ("model", "example", "mode", "source", "status")
    print("  ".join(h.ljust(w) for h, w in zip(header, widths, strict=True)))
    for row in rows:
        print("  ".join(str(c).ljust(w) for c, w in zip(row, widths, strict=True)).rstrip())
    print()
    for m in models:
        c = m.status_counts()
        print(f"{m.name}: frames {len(m.examples)}, verified {c['verified']}, errata {c['erratum']}, illegible {c['illegible']}")
    return 0


def cmd_export(args: argparse.Namespace) -> int:
    from .export import export_model

    try:
        data = export_model(args.model)
    except CompileError as exc:
        return _report(exc.diagnostics)
    json.dump(data, sys.stdout, indent=2, ensure_ascii=False)
    sys.stdout.write("\n")
    return 0


def cmd_new(args: argparse.Namespace) -> int:
    import re

    from .compiler import MAPS_DIR
    from .render import scaffold

    target = Path(args.dir) / f"{args.model}.yaml" if args.dir else MAPS_DIR / f"{args.model}.yaml"
    if not re.fullmatch(r"[a-z][a-z0-9_]*", args.model):
        print(f"{target}:1:1: error: model id {args.model!r} must be a lower-case identifier", file=sys.stderr)
        return 1
    if target.exists():
        print(f"{target}:1:1: error: file exists; not overwritten", file=sys.stderr)
        return 1
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text(scaffold(args.model), encoding="utf-8")
    print(f"wrote {target}")
    return 0


def cmd_simulate(args: argparse.Namespace) -> int:
    from .runtime.simserve import serve_cli

    code: int = serve_cli(args)
    return code


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="drivemap", description="Register-map compiler for Modbus drives.")
    sub = p.add_subparsers(dest="command", required=True)
    s = sub.add_parser("validate", help="validate maps (default: every map in maps/)")
    s.add_argument("paths", nargs="*")
    s.set_defaults(func=cmd_validate)
    s = sub.add_parser("build", help="validate, verify examples, render generated/")
    s.add_argument("--out", default="generated")
    s.set_defaults(func=cmd_build)
    s = sub.add_parser("check", help="exit 1 if generated/ differs from what build would write")
    s.add_argument("--out", default="generated")
    s.set_defaults(func=cmd_check)
    s = sub.add_parser("examples", help="verify every example frame and print a table")
    s.add_argument("model", nargs="?")
    s.set_defaults(func=cmd_examples)
    s = sub.add_parser("export", help="print the normalized model")
    s.add_argument("model")
    s.add_argument("--format", choices=["json"], default="json")
    s.set_defaults(func=cmd_export)
    s = sub.add_parser("new", help="scaffold maps/MODEL.yaml")
    s.add_argument("model")
    s.add_argument("--dir", default=None, help="folder for the new map (default: maps/)")
    s.set_defaults(func=cmd_new)
    s = sub.add_parser("simulate", help="run a model's simulator")
    s.add_argument("model")
    where = s.add_mutually_exclusive_group(required=True)
    where.add_argument("--tcp", metavar="HOST:PORT")
    where.add_argument("--serial", metavar="DEVICE")
    s.add_argument("--mode", choices=["rtu", "ascii"], default=None)
    s.add_argument("--baudrate", type=int, default=None)
    s.add_argument("--unit", type=int, action="append", dest="units")
    s.add_argument("--state", default=None, help="JSON file keeping EEPROM-class registers across restarts")
    s.add_argument("--realistic-timing", action="store_true")
    s.add_argument("--allow-remote", action="store_true", help="allow binding to a non-loopback address")
    s.set_defaults(func=cmd_simulate)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    args = parser().parse_args(argv)
    try:
        result: int = args.func(args)
        return result
    except CompileError as exc:
        return _report(exc.diagnostics)
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        return 0


if __name__ == "__main__":
    sys.exit(main())

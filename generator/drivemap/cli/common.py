"""What the verbs share: the command-line error, the parser class, the project of the working
directory, compiling its maps and reporting located errors."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn

from drivemap.diagnostics import CompileError, Diagnostic, Location
from drivemap.frontend.project import Project, display, load_project
from drivemap.model.nodes import Model

if TYPE_CHECKING:
    from drivemap.backends.output import Change
    from drivemap.compiler import MapCheck


class UsageError(Exception):
    """A bad command line: printed as ``drivemap VERB: error: ...`` with exit status 1."""

    def __init__(self, prog: str, message: str) -> None:
        super().__init__(f"{prog}: error: {message}")


class Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        raise UsageError(self.prog, message)


def project_of(args: argparse.Namespace, maps: Sequence[str] | None = None) -> Project:
    return load_project(
        maps=maps or getattr(args, "maps", None),
        out=getattr(args, "out", None),
        package=getattr(args, "package", None),
        docs=getattr(args, "docs", None),
        behaviours=getattr(args, "behaviours", None),
    )


def compile_files(files: Sequence[Path], checks: Sequence[MapCheck] = ()) -> tuple[list[Model], list[Diagnostic]]:
    """Compile every map with ``checks`` (outputs' own checks; none: the front end alone)."""
    from drivemap.compiler import compile_cached

    models: list[Model] = []
    errors: list[Diagnostic] = []
    for path in files:
        try:
            models.append(compile_cached(path, checks))
        except CompileError as exc:
            errors.extend(exc.diagnostics)
    first: dict[str, Model] = {}
    for model in models:
        if model.name in first:
            errors.append(Diagnostic(Location(model.path, model_line(model.path), 1),
                                     f"model id {model.name!r} is also the id of {first[model.name].path}: "
                                     "one map per model (the generated package would come from one of them)",
                                     related=((Location(first[model.name].path, 1, 1), "the other map"),)))
        first.setdefault(model.name, model)
    return models, errors


def model_line(path: str) -> int:
    try:
        lines = Path(path).read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError):
        return 1
    return next((n for n, line in enumerate(lines, 1) if line.strip().startswith("model:")), 1)


def project_models(project: Project, checks: Sequence[MapCheck] = ()) -> list[Model]:
    files = project.map_files()
    if not files:
        where = ", ".join(display(m) for m in project.maps)
        raise CompileError([Diagnostic(Location(where, 1, 1), "no maps found (run `drivemap new MODEL`, or set maps)")])
    models, errors = compile_files(files, checks)
    if errors:
        raise CompileError(errors)
    return models


def report(errors: Sequence[Diagnostic]) -> int:
    for d in errors:
        print(d.format(), file=sys.stderr)
    if errors:
        count = len(errors)
        print(f"{count} error{'s' if count != 1 else ''}", file=sys.stderr)
        return 1
    return 0


def summary(model: Model) -> str:
    counts = model.status_counts()
    cells = sum(r.count for r in model.registers)
    open_items = sum(len(r.review) for r in model.registers)
    reviewed = sum(1 for r in model.registers if r.review)
    text = (
        f"{model.name}: {len(model.registers)} registers ({cells} with array elements), "
        f"{len(model.enums)} enums, {len(model.examples)} examples "
        f"({counts['verified']} verified, {counts['erratum']} errata, {counts['illegible']} illegible)"
    )
    if open_items:
        text += f", {open_items} open for review on {reviewed} register{'s' if reviewed != 1 else ''}"
    if model.device.evidence:
        text += f", evidence: {model.device.evidence}"
    return text


def project_flags(p: argparse.ArgumentParser, *, out: bool = True) -> None:
    g = p.add_argument_group("project settings (override [tool.drivemap])")
    if out:
        g.add_argument("--out", default=None, help="the generated package's folder")
        g.add_argument("--package", default=None, help="the generated package's import name")
        g.add_argument("--docs", default=None, help="the generated docs' folder")
    g.add_argument("--maps", action="append", default=None, metavar="PATH", help="map file or folder (repeatable)")
    g.add_argument("--behaviours", action="append", default=None, metavar="MODULE",
                   help="module that registers simulator behaviours (repeatable)")
    p.add_argument("--no-cache", action="store_true",
                   help="compile every map anew: neither read nor write the compile cache (DRIVEMAP_NO_CACHE=1)")


def write_change(change: Change) -> None:
    """Carry out a planned change; a folder or file the system refuses is a located error."""
    from drivemap.backends import output

    try:
        output.write(change)
    except OSError as exc:
        where = display(change.root)
        raise CompileError([Diagnostic(Location(where, 1, 1), f"cannot write the output here: "
                                                              f"{exc.strerror or exc}")]) from None

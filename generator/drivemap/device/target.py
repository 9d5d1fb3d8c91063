"""The model a live verb talks to: its map, compiled in memory, and the generated client classes.

``MODEL`` is a model id of the project (``ev``), a seed map shipped with drivemap, or a map path
(``maps/ev.yaml``); nothing is built or written.
"""

from __future__ import annotations

import shlex
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property
from types import ModuleType
from typing import Any

from drivemap import cache
from drivemap.compiler import compile_cached, resolve_map
from drivemap.diagnostics import CompileError, Diagnostic, Location
from drivemap.frontend.load import load_file
from drivemap.frontend.project import Project, load_project
from drivemap.model.nodes import Model, Register
from drivemap.runtime.spec import DeviceSpec


@dataclass
class Target:
    """One compiled map, its runtime spec and its in-memory generated package (built on first use:
    a verb that weighs many maps, like scan, builds the packages of the few it reads values of)."""

    model: Model
    spec: DeviceSpec
    _package: ModuleType | None = None
    _lines: dict[tuple[str | int, ...], int] = field(default_factory=dict)

    @property
    def package(self) -> ModuleType:
        if self._package is None:
            from drivemap.runtime.package import load_package

            self._package = load_package(self.spec)
        return self._package

    @property
    def client_class(self) -> Any:
        return self.package.Client

    @property
    def codecs(self) -> Any:
        return self.package.CODECS

    def where(self, reg: Register) -> str:
        """``maps/ev.yaml:580``: where the register is defined (in the base map for a register a
        variant inherits)."""
        loc = self.register_location(reg)
        return f"{loc.path}:{loc.line}"

    def register_location(self, reg: Register) -> Location:
        index = next(i for i, r in enumerate(self.model.registers) if r.name == reg.name)
        loc: Location = self._document_positions.at(("registers", index))
        return loc

    @cached_property
    def _document_positions(self) -> Any:
        from drivemap.frontend.family import resolve

        doc = load_file(self.model.path)
        return resolve(doc)[0].positions if self.model.variant is not None else doc.positions

    def line_of(self, *where: str | int) -> int:
        """Line of an item of the map (``"reserved", 2`` or ``"protocol", "exceptions", 1``)."""
        return int(self._document_positions.at(tuple(where)).line)

    def exception_line(self, code: int) -> int | None:
        for i, item in enumerate(self.model.protocol.exceptions):
            if item.code == code:
                return self.line_of("protocol", "exceptions", i)
        return None

    def register_at(self, address: int, table: str) -> tuple[Register, int] | None:
        """The register cell (register, element index) of ``table`` that holds ``address``, if any
        (the four tables have their own addresses: holding 0x0002 is not input 0x0002)."""
        for reg in self.model.registers:
            if reg.table != table:
                continue
            for i in range(reg.count):
                start = reg.element_address(i)
                if start <= address < start + reg.words:
                    return reg, i
        return None


def project_of(maps: Sequence[str] | None) -> Project:
    return load_project(maps=maps)


def load_target(name: str, project: Project | None = None) -> Target:
    """Compile ``name`` (model id or map path; the compile cache reused); its package is built when first used."""
    model = compile_cached(resolve_map(name, project or load_project()))
    return Target(model, spec_of(model))


def spec_of(model: Model) -> DeviceSpec:
    """``spec_from_model(model)``, kept in the compile cache beside the model it projects (a verb
    that loads the whole catalogue projects each map once, not on every run)."""
    from drivemap.model.spec import spec_from_model

    key = model.cache_key
    spec = cache.load("spec", key) if key is not None else None
    if isinstance(spec, DeviceSpec):
        return spec
    spec = spec_from_model(model)
    if key is not None:
        cache.store("spec", key, spec)
    return spec


def command_line_error(argv: Sequence[str], index: int, message: str,
                       related: tuple[tuple[Location, str], ...] = ()) -> CompileError:
    """A located error about ``argv[index]``: ``<command line>:1:COL: error: ...``.

    The column counts in the command as the shell shows it (``drivemap VERB ARG ...``).
    """
    shown = ["drivemap", *(shlex.quote(a) for a in argv)]
    col = 1 + sum(len(s) + 1 for s in shown[: index + 1])
    return CompileError([Diagnostic(Location("<command line>", 1, col), message, related=related)])


def register_note(target: Target, reg: Register) -> tuple[tuple[Location, str], ...]:
    """A note pointing at the register's map line."""
    bounds = []
    if reg.min is not None:
        bounds.append(f"min {reg.min:g}")
    if reg.max is not None:
        bounds.append(f"max {reg.max:g}")
    extra = f" ({', '.join(bounds)}{' ' + reg.unit if reg.unit and bounds else ''})" if bounds else ""
    loc = target.register_location(reg)
    return ((Location(loc.path, loc.line, 5), f"{reg.name} is defined here{extra}"),)


def locate_error(token: str, message: str, target: Target | None = None, reg: Register | None = None,
                 argv: Sequence[str] | None = None) -> CompileError:
    """A located error about the command-line argument ``token``."""
    args = list(argv) if argv is not None else sys.argv[1:]
    index = args.index(token) if token in args else len(args)
    if token not in args:
        args.append(token)
    related = register_note(target, reg) if target is not None and reg is not None else ()
    return command_line_error(args, index, message, related)

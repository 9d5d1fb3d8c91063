"""Where known maps put readable words: the runs ``probe`` reads once inside refused blocks.

The shipped maps' generated specs (and the ``--map`` given) name the register blocks devices of
those families answer; a run of consecutive readable words of any of them is one hint. A hint is a
read like any other: it proves only what the device answers.
"""

from __future__ import annotations

import importlib
import sys

from drivemap.frontend.project import Project
from drivemap.runtime.spec import DeviceSpec

__all__ = ["candidate_specs", "candidates", "hint_runs", "known_specs"]


def known_specs() -> list[DeviceSpec]:
    """The generated specs of the maps drivemap ships (those whose package is installed)."""
    from drivemap.compiler import bundled_maps

    specs = []
    for path in bundled_maps():
        try:
            module = importlib.import_module(f"drivemap_models.{path.stem}.spec")
        except ImportError:
            continue
        spec = getattr(module, "SPEC", None)
        if isinstance(spec, DeviceSpec):
            specs.append(spec)
    return specs


def candidate_specs(project: Project) -> list[tuple[str, DeviceSpec]]:
    """What a probe's findings are weighed against: (whose map, spec) of the project's maps, then the
    shipped maps and the catalogue maps whose model id the project does not have (the user's map wins).
    Compiled through the compile cache; a map that does not compile is left out with a line on stderr."""
    from drivemap.compiler import compile_cached
    from drivemap.device.target import spec_of
    from drivemap.diagnostics import CompileError
    from drivemap.frontend.project import catalogue_maps, shipped_maps

    out: list[tuple[str, DeviceSpec]] = []
    seen: set[str] = set()
    for whose, paths in (("the project's map", project.map_files()), ("the shipped map", shipped_maps()),
                         ("the catalogue map", catalogue_maps())):
        for path in paths:
            if path.stem in seen:
                continue
            try:
                model = compile_cached(path)
            except CompileError as exc:
                print(f"drivemap probe: not weighed: {exc.diagnostics[0].format()}", file=sys.stderr)
                continue
            seen.add(model.name)
            out.append((whose, spec_of(model)))
    return out


def _words(spec: DeviceSpec, tables: list[str]) -> set[tuple[str, int]]:
    """Every word of a readable register of ``tables`` that is on no page (what reads at power-up)."""
    out: set[tuple[str, int]] = set()
    for reg in spec.registers:
        if reg.table in tables and reg.readable and reg.page is None:
            for i in range(reg.count):
                start = reg.element_address(i)
                out.update((reg.table, a) for a in range(start, start + reg.words) if a <= 0xFFFF)
    return out


def candidates(specs: list[DeviceSpec], values: dict[str, dict[int, int]], tables: list[str],
               ranges: list[tuple[int, int]]) -> list[tuple[str, int, int]]:
    """The maps whose every readable word in the probed ranges answered: (model, its words there, the
    words read that it names), the map naming most of what was read first. A candidate to verify, not
    an identification: other devices may answer the same addresses."""
    read = {(t, a) for t, cells in values.items() for a in cells}
    out = []
    for spec in specs:
        words = {(t, a) for t, a in _words(spec, tables) if any(lo <= a <= hi for lo, hi in ranges)}
        if words and words <= read:
            out.append((spec.name, len(words), len(words & read)))
    return sorted(out, key=lambda c: (-c[2], c[0]))


def hint_runs(specs: list[DeviceSpec], tables: list[str]) -> dict[str, list[tuple[int, int]]]:
    """Per table: the inclusive runs of consecutive readable words of each spec (every page), merged
    per spec, deduplicated across specs."""
    out: dict[str, set[tuple[int, int]]] = {t: set() for t in tables}
    for spec in specs:
        words: dict[str, set[int]] = {t: set() for t in tables}
        for reg in spec.registers:
            if reg.table in words and reg.readable:
                for i in range(reg.count):
                    start = reg.element_address(i)
                    words[reg.table].update(a for a in range(start, start + reg.words) if a <= 0xFFFF)
        for table, cells in words.items():
            run: list[int] = []
            for a in sorted(cells):
                if run and a != run[-1] + 1:
                    out[table].add((run[0], run[-1]))
                    run = []
                run.append(a)
            if run:
                out[table].add((run[0], run[-1]))
    return {t: sorted(r) for t, r in out.items()}

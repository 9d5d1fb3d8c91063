"""What a project's build produces, folder by folder, and models served straight from a map.

``drivemap build`` runs the ``python`` exporter into the project's ``out`` folder, the ``docs``
exporter into its ``docs`` folder and every committed export of ``[[tool.drivemap.exports]]``;
:func:`outputs_by_root` groups those files by the folder whose manifest owns them.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, NoReturn

from drivemap.backends.exporters import available
from drivemap.backends.exporters.base import Exporter, OptionError, Options
from drivemap.backends.exporters.docs import DocsExporter
from drivemap.backends.exporters.python import PythonExporter
from drivemap.backends.output import Change
from drivemap.diagnostics import CompileError, Diagnostic, Location
from drivemap.frontend.project import Project, display
from drivemap.model.nodes import Model
from drivemap.model.spec import spec_from_model

__all__ = ["entry_options", "export_files", "options_for", "outputs_by_root", "outputs_cached", "simulator_factory",
           "settled"]


def build_checks() -> tuple[Exporter, ...]:
    """The checks of the outputs ``drivemap build`` always writes (the python package's names, the docs
    page's anchors), which ``build`` and ``check`` hand to the compiler."""
    return (PythonExporter(), DocsExporter())


def options_for(project: Project, values: Mapping[str, Any] | None = None) -> Options:
    return Options(package=project.package, root=project.root, out=project.out, docs=project.docs,
                   values=dict(values or {}))


def _owner(path: Path, roots: Sequence[Path]) -> Path:
    """The outermost root that contains ``path``."""
    for root in sorted(roots, key=lambda r: len(r.parts)):
        if path.is_relative_to(root):
            return root
    return path.parent


def outputs_by_root(project: Project, models: Sequence[Model]) -> dict[Path, tuple[dict[str, str], bool]]:
    """root folder -> (relative path -> text, prune?) for everything ``build`` writes."""
    options = options_for(project)
    out, docs = project.out.resolve(), project.docs.resolve()
    files: dict[Path, str] = {}
    for folder, exporter in ((out, PythonExporter()), (docs, DocsExporter())):
        for rel, text in exporter.render_all(models, options).items():
            files[folder / rel] = text
    by_name = {m.name: m for m in models}
    writers = dict.fromkeys(files, "drivemap build's own output (out/docs)")
    for entry in project.exports:
        model = by_name.get(entry.model)
        where = Location(display(project.config or project.root), entry.line, 1)
        _check_target(project, entry.output.resolve(), where, writers)
        writers[entry.output.resolve()] = f"the export at line {entry.line}"
        if model is None:
            raise CompileError([Diagnostic(where, f"exports: no map of model {entry.model!r} in the project")])
        exporter_cls = available().get(entry.format)
        if exporter_cls is None:
            raise CompileError([Diagnostic(where, f"exports: no exporter named {entry.format!r}")])
        chosen = exporter_cls()
        try:
            rendered = chosen.render(model, options_for(project, entry_options(chosen, entry.options)))
        except OptionError as exc:
            raise CompileError([Diagnostic(where, f"exports: {entry.format} for {entry.model}: {exc}")]) from None
        files[entry.output.resolve()] = _single(rendered, entry.format, where)
    roots = [out, docs]
    grouped: dict[Path, tuple[dict[str, str], bool]] = {}
    for path, text in files.items():
        root = _owner(path, roots)
        prune = root in roots
        grouped.setdefault(root, ({}, prune))[0][path.relative_to(root).as_posix()] = text
    return grouped


def outputs_cached(project: Project, models: Sequence[Model]) -> dict[Path, tuple[dict[str, str], bool]]:
    """:func:`outputs_by_root`, from the cache (:mod:`drivemap.cache`) when the same drivemap rendered
    the same models (each from :func:`~drivemap.compiler.compile_cached`) with the same project
    settings, from the same working directory, before; stored after rendering otherwise."""
    from drivemap import cache
    from drivemap.compiler import content_key

    keys = [content_key(m) for m in models]
    exporters = available()
    ours = all(e.__module__.startswith("drivemap.") for e in (exporters.get(x.format) for x in project.exports)
               if e is not None)
    if not cache.enabled() or None in keys or not ours:
        return outputs_by_root(project, models)
    settings = repr((os.getcwd(), str(project.root), str(project.config), [str(m) for m in project.maps],
                     str(project.out), project.package, str(project.docs), project.behaviours,
                     [(e.format, e.model, str(e.output), sorted((str(k), repr(v)) for k, v in e.options.items()),
                       e.line) for e in project.exports]))
    entry = cache.key("build", settings, *(k for k in keys if k is not None))
    hit = cache.load("build", entry)
    if isinstance(hit, dict) and all(isinstance(k, Path) and isinstance(v, tuple) and len(v) == 2
                                     and isinstance(v[0], dict) and isinstance(v[1], bool) for k, v in hit.items()):
        return hit
    grouped = outputs_by_root(project, models)
    cache.store("build", entry, grouped)
    return grouped


def settled(changes: Sequence[Change]) -> bool:
    """Whether carrying out ``changes`` would touch nothing: no file to write or delete, every
    manifest already what it would be, no staging left by an interrupted build (a no-change
    ``drivemap build`` then neither locks nor writes, so no file's or folder's mtime changes)."""
    from drivemap.backends import output

    return all(not c.errors and output.settled(c) for c in changes)


class _OptionParser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        raise OptionError(message)


def entry_options(exporter: Exporter, table: Mapping[str, Any]) -> dict[str, Any]:
    """The ``options`` table of an ``[[tool.drivemap.exports]]`` entry, read as the same options on
    ``drivemap export``'s command line: keys are the long option names (``ha-version`` or
    ``ha_version``), ``true`` stands for a flag, a list for a repeatable option. The exporter's
    ``options_class`` reads it directly (the schema its command line is built from); a plugin that
    adds its own arguments instead has the table read through its parser."""
    if type(exporter).add_arguments is Exporter.add_arguments:
        return exporter.options_class.from_table(table).values()
    parser = _OptionParser(prog=exporter.name, add_help=False)
    exporter.add_arguments(parser)
    flags = {a.dest: a for a in parser._actions if a.option_strings}
    argv: list[str] = []
    for key, value in table.items():
        action = flags.get(str(key).replace("-", "_"))
        if action is None:
            known = ", ".join(sorted(a.option_strings[-1].lstrip("-") for a in flags.values())) or "none"
            raise OptionError(f"unknown option {key!r} (options: {known})")
        flag = action.option_strings[-1]
        if value is True:
            argv.append(flag)
        elif value is False:
            continue
        else:
            for item in value if isinstance(value, list) else [value]:
                argv += [flag, str(item)]
    return vars(parser.parse_args(argv))


def _check_target(project: Project, target: Path, where: Location, writers: Mapping[Path, str]) -> None:
    """A committed export's output must be a new file of the project, outside its maps."""
    shown = display(target)
    if not target.is_relative_to(project.root.resolve()):
        problem = "is outside the project (exports write inside it)"
    elif any(target.is_relative_to(m.resolve()) for m in project.maps if m.is_dir() or not m.suffix):
        problem = "is inside the maps folder (choose another output)"
    elif any(target == m.resolve() for m in project.map_files()):
        problem = "is a map of the project"
    elif target in writers:
        problem = f"is also written by {writers[target]}"
    else:
        return
    raise CompileError([Diagnostic(where, f"exports: output {shown} {problem}")])


def _single(files: Mapping[str, str], name: str, where: Location) -> str:
    if len(files) != 1:
        raise CompileError([Diagnostic(where, f"exports: exporter {name!r} writes several files; "
                                              "committed exports take single-file exporters")])
    return next(iter(files.values()))


def export_files(exporter: Exporter, model: Model, project: Project, values: Mapping[str, Any],
                 output: str | None) -> dict[str, str]:
    """The files of ``drivemap export`` (for a multi-file exporter writing to a folder, the
    folder is where the docs or package links point)."""
    options = options_for(project, values)
    if output is not None and exporter.multi_file:
        target = Path(output).resolve()
        options = Options(package=options.package, root=options.root, out=target, docs=target, values=options.values)
    return exporter.render_all([model], options)


def simulator_factory(model: Model, project: Project) -> Any:
    """A simulator factory for a compiled map (no build needed): its spec rendered in memory and
    the behaviour the project or an installed distribution registers for the model id."""
    from drivemap.runtime.sim.behaviours import behaviour_for, load_modules
    from drivemap.runtime.sim.simulator import Simulator

    root = str(project.root)
    added = bool(project.behaviours) and root not in sys.path
    if added:  # the project's own modules, importable while they load (and no longer after)
        sys.path.insert(0, root)
    try:
        load_modules(project.behaviours)
    except ImportError as exc:
        where = Location(display(project.config or project.root), 1, 1)
        raise CompileError([Diagnostic(where, f"behaviours: cannot import {exc.name or exc}: {exc}")]) from None
    finally:
        if added and root in sys.path:
            sys.path.remove(root)
    spec = spec_from_model(model)

    def factory(units: Sequence[int] = (1,), **kwargs: Any) -> Simulator:
        return Simulator(spec, units, behaviour=behaviour_for(model.name), **kwargs)

    factory.spec = spec  # type: ignore[attr-defined]  # presets are checked against it before the start
    factory.read_values = read_values_yaml  # type: ignore[attr-defined]  # --values FILE: YAML or JSON
    factory.enum_names = {reg.name: {v.name.upper(): v.value for v in model.enum(reg.enum).members}  # type: ignore[attr-defined]
                          for reg in model.registers if reg.enum is not None}
    return factory


def read_values_yaml(path: Path) -> list[tuple[str, Any, int, int]]:
    """``drivemap simulate --values FILE``: a YAML (or JSON) mapping of cell names to engineering
    values, each entry located at its key (the checks are :func:`drivemap.runtime.sim.presets.from_file`'s)."""
    import yaml

    from drivemap.runtime.sim.presets import PresetError

    where = str(path)
    try:
        node = yaml.compose(path.read_text(encoding="utf-8"), Loader=yaml.SafeLoader)
    except OSError as exc:
        raise PresetError(f"{where}:1:1: error: cannot read values: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise PresetError(f"{where}:1:1: error: cannot read values: not UTF-8 text") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line, col = (mark.line + 1, mark.column + 1) if mark is not None else (1, 1)
        raise PresetError(f"{where}:{line}:{col}: error: not YAML or JSON: {getattr(exc, 'problem', exc)}") from None
    if node is None:
        return []
    if not isinstance(node, yaml.MappingNode):
        raise PresetError(f"{where}:{node.start_mark.line + 1}:{node.start_mark.column + 1}: error: "
                          "expected a mapping of register names to values")
    loader = yaml.SafeLoader("")
    return [(str(key.value), loader.construct_object(value, deep=True), key.start_mark.line + 1,
             key.start_mark.column + 1) for key, value in node.value]


def render_tree(models: Sequence[Model], options: Options | None = None) -> dict[str, str]:
    """Every file of a build in the default layout (docs in ``docs/`` inside the package folder)."""
    options = options or Options()
    files = PythonExporter().render_all(models, options)
    files.update({f"docs/{rel}": text for rel, text in DocsExporter().render_all(models, options).items()})
    return files


def write_tree(root: Path, files: Mapping[str, str], *, force: bool = False) -> None:
    """Write ``files`` into ``root`` as ``drivemap build`` does (manifest, staged, pruned)."""
    from drivemap.backends import output

    with output.locked([root]):
        output.write(output.plan(root, files, prune=True, force=force))


def export_model(name: str) -> dict[str, Any]:
    """Compile the map of a model id or path and return its export contract (``--format json``)."""
    from drivemap.backends.export import export
    from drivemap.compiler import load_model

    return export(load_model(name))

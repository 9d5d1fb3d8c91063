"""Project discovery: where the maps are, where the output goes, what the package is called.

drivemap finds its project the way ruff, mypy and pytest do: from the working directory upwards,
the first ``pyproject.toml`` with a ``[tool.drivemap]`` table or the first ``drivemap.toml``
(whose top level is the same table). Without either, the working directory is the project and
every setting has its default. Every path in the table is relative to the file that holds it;
command-line flags win over the table.

=============  ===============================  =============================================
key            default                          meaning
=============  ===============================  =============================================
maps           ``"maps"``                       a folder of ``*.yaml`` maps (and its subfolders), or a list of
                                                files/folders
exclude        ``[]``                           files/folders under ``maps`` that are not the project's maps
                                                (``["maps/catalogue"]``): build, check and validate skip them;
                                                a model id still finds them (like a shipped map)
out            ``"generated"``                  the generated package's folder
package        the name of ``out``'s folder     the generated package's import name
docs           ``"<out>/docs"``                 the generated Markdown
behaviours     ``[]``                           importable modules that register simulator behaviours
exports        ``[]``                           committed exports: ``{format, model, output, options}``
=============  ===============================  =============================================
"""

from __future__ import annotations

import keyword
import os
import re
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from drivemap.diagnostics import CompileError, Diagnostic, Location

__all__ = ["SHIPPED_MAPS", "ExportEntry", "Project", "catalogue_maps", "display", "find_project", "load_project",
           "shipped_maps"]

CONFIG_KEYS = ("maps", "exclude", "out", "package", "docs", "behaviours", "exports")
#: The maps shipped inside the package: drivemap's own (``*.yaml``) and the catalogue
#: (``catalogue/<source>/*.yaml``), in the repository a link to its ``maps/`` folder.
SHIPPED_MAPS = Path(__file__).resolve().parent.parent / "data" / "maps"
_DOTTED = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*")


def display(path: str | os.PathLike[str]) -> str:
    """A path as messages show it: relative to the working directory when it is below it."""
    p = Path(path)
    if not p.is_absolute():
        return str(p)
    try:
        rel = os.path.relpath(p)
    except ValueError:
        return str(p)
    return str(p) if rel.startswith("..") else rel


@dataclass(frozen=True)
class ExportEntry:
    """One committed export: ``drivemap build`` writes it and ``drivemap check`` compares it."""

    format: str
    model: str
    output: Path
    options: Mapping[str, Any] = field(default_factory=dict)
    line: int = 1  #: where the entry stands in the configuration file


@dataclass(frozen=True)
class Project:
    """A drivemap project: its root, its settings (absolute paths) and where they came from."""

    root: Path
    config: Path | None
    maps: tuple[Path, ...]
    out: Path
    package: str
    docs: Path
    behaviours: tuple[str, ...] = ()
    exports: tuple[ExportEntry, ...] = ()
    exclude: tuple[Path, ...] = ()
    #: the notes already printed about which map a model id finds (each is said once per project)
    said: set[str] = field(default_factory=set, compare=False, repr=False)

    def map_files(self) -> list[Path]:
        """Every map of the project: the files named, and ``*.yaml`` in the folders named and their
        subfolders (sorted; hidden names left out, and what ``exclude`` names below a folder)."""
        return [p for p, out in self._walk() if not out]

    def excluded_files(self) -> list[Path]:
        """The maps below the ``maps`` folders that ``exclude`` leaves out (found by model id, not built)."""
        return [p for p, out in self._walk() if out]

    def _walk(self) -> list[tuple[Path, bool]]:
        """(file, excluded) of every map the entries name; a file or folder named outright is never
        excluded (``drivemap validate maps/catalogue`` checks what it names)."""
        files: list[tuple[Path, bool]] = []
        for entry in self.maps:
            if entry.is_dir():
                top = entry.resolve()
                below = [ex.resolve() for ex in self.exclude if top in ex.resolve().parents]
                for p in sorted((p for p in entry.rglob("*.yaml")
                                 if not any(part.startswith(".") for part in p.relative_to(entry).parts)),
                                key=lambda p: _folder_order(p.relative_to(entry))):
                    full = top / p.relative_to(entry)
                    files.append((p, any(full == ex or ex in full.parents for ex in below)))
            elif entry.exists() or entry.suffix in (".yaml", ".yml"):
                files.append((entry, False))  # a missing file is reported where it is read
        return files

    def maps_folder(self) -> Path:
        """Where ``drivemap new`` writes: the first folder of ``maps`` (or the folder of its first file)."""
        for entry in self.maps:
            if entry.is_dir() or entry.suffix not in (".yaml", ".yml"):
                return entry
        return self.maps[0].parent

    def relative(self, path: str | os.PathLike[str]) -> str:
        """``path`` relative to the project root (posix separators); absolute if outside it."""
        full = Path(path).resolve()
        try:
            return full.relative_to(self.root.resolve()).as_posix()
        except ValueError:
            return full.as_posix()

    def find_map(self, name: str) -> Path | None:
        """The project's map of model id ``name`` (``maps/<name>.yaml``), if it has one."""
        for path in self.map_files():
            if path.stem == name:
                return path
        return None


def find_project(start: Path | None = None) -> tuple[Path, Path | None, dict[str, Any]]:
    """(root, config file or None, the ``[tool.drivemap]`` table) for the working directory."""
    here = (start or Path.cwd()).resolve()
    for folder in (here, *here.parents):
        pyproject = folder / "pyproject.toml"
        if pyproject.is_file():
            data = _read_toml(pyproject)
            table = data.get("tool", {}).get("drivemap") if isinstance(data.get("tool"), dict) else None
            if isinstance(table, dict):
                return folder, pyproject, table
            if table is not None:
                raise _config_error(pyproject, "[tool.drivemap] must be a table")
        own = folder / "drivemap.toml"
        if own.is_file():
            return folder, own, _read_toml(own)
    return here, None, {}


def _read_toml(path: Path) -> dict[str, Any]:
    try:
        with open(path, "rb") as handle:
            return tomllib.load(handle)
    except tomllib.TOMLDecodeError as exc:
        line, col = _toml_position(str(exc))
        raise CompileError([Diagnostic(Location(display(path), line, col), f"invalid TOML: {exc}")]) from None
    except UnicodeDecodeError as exc:
        raw = path.read_bytes()
        line = raw.count(b"\n", 0, exc.start) + 1
        col = exc.start - (raw.rfind(b"\n", 0, exc.start) + 1) + 1
        raise CompileError([Diagnostic(Location(display(path), line, col), "invalid TOML: not UTF-8 text")]) from None
    except OSError as exc:
        raise _config_error(path, f"cannot read: {exc.strerror}") from None


def _toml_position(message: str) -> tuple[int, int]:
    match = re.search(r"line (\d+), column (\d+)", message)
    return (int(match.group(1)), int(match.group(2))) if match else (1, 1)


def _config_error(path: Path, message: str) -> CompileError:
    return CompileError([Diagnostic(Location(display(path), _key_line(path, message), 1), message)])


def _key_line(path: Path, message: str) -> int:
    """The line of the key a message names (``tool.drivemap.out: ...``), or 1."""
    match = re.match(r"(?:tool\.drivemap\.)?(\w+)", message)
    if not match:
        return 1
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError):
        return 1
    in_table = path.name != "pyproject.toml"
    for number, line in enumerate(lines, 1):
        stripped = line.strip()
        if stripped.startswith("["):
            in_table = path.name != "pyproject.toml" or stripped.startswith(("[tool.drivemap]", "[[tool.drivemap."))
            continue
        if in_table and re.match(rf"{re.escape(match.group(1))}\s*=", stripped):
            return number
    return 1


def load_project(
    start: Path | None = None,
    *,
    maps: Sequence[str] | None = None,
    out: str | None = None,
    package: str | None = None,
    docs: str | None = None,
    behaviours: Sequence[str] | None = None,
) -> Project:
    """The project of the working directory, with command-line overrides (relative to the cwd)."""
    root, config, table = find_project(start)
    where = config if config is not None else root / "pyproject.toml"
    prefix = "tool.drivemap." if where.name == "pyproject.toml" else ""
    unknown = sorted(set(table) - set(CONFIG_KEYS))
    if unknown:
        raise _config_error(where, f"{prefix}{unknown[0]}: unknown setting (known: {', '.join(CONFIG_KEYS)})")

    def string(key: str) -> str | None:
        value = table.get(key)
        if value is not None and not isinstance(value, str):
            raise _config_error(where, f"{prefix}{key}: expected a string, got {type(value).__name__}")
        return value

    def strings(key: str) -> list[str] | None:
        value = table.get(key)
        if value is None:
            return None
        if isinstance(value, str):
            return [value]
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise _config_error(where, f"{prefix}{key}: expected a string or a list of strings")
        return list(value)

    cwd = Path.cwd()
    map_entries = [cwd / m for m in maps] if maps else [root / m for m in (strings("maps") or ["maps"])]
    out_dir = (cwd / out) if out else root / (string("out") or "generated")
    # --out without --docs puts the docs in <out>/docs: a build redirected on the command line
    # never writes into the configured docs folder.
    configured_docs = None if out else string("docs")
    docs_dir = (cwd / docs) if docs else (root / configured_docs if configured_docs else out_dir / "docs")
    pkg = package or string("package") or out_dir.name
    _check_package(pkg, package, string("package"), out, string("out"), out_dir, where, prefix)
    exclude = tuple(root / e for e in (strings("exclude") or []))
    mods = list(behaviours) if behaviours else (strings("behaviours") or [])
    for mod in mods:
        if not _DOTTED.fullmatch(mod):
            if behaviours:  # from the command line: no file holds it
                raise CompileError([Diagnostic(Location("--behaviours", 1, 1), f"{mod!r} is not a module name")])
            raise _config_error(where, f"{prefix}behaviours: {mod!r} is not a module name")
    return Project(
        root=root,
        config=config,
        maps=tuple(map_entries),
        out=out_dir,
        package=pkg,
        docs=docs_dir,
        behaviours=tuple(mods),
        exports=_exports(table.get("exports"), root, where, prefix),
        exclude=exclude,
    )


def shipped_maps() -> list[Path]:
    """The maps that ship with drivemap (``data/maps/*.yaml``, sorted by name)."""
    return sorted(SHIPPED_MAPS.glob("*.yaml")) if SHIPPED_MAPS.is_dir() else []


def catalogue_maps() -> list[Path]:
    """The catalogue maps that ship with drivemap (``data/maps/catalogue/<source>/*.yaml``, sorted by
    source folder and name)."""
    folder = SHIPPED_MAPS / "catalogue"
    if not folder.is_dir():
        return []
    return sorted((p for p in folder.rglob("*.yaml") if not any(part.startswith(".") for part in
                                                                p.relative_to(folder).parts)),
                  key=lambda p: _folder_order(p.relative_to(folder)))


def _folder_order(rel: Path) -> tuple[bool, tuple[str, ...]]:
    """A folder's own files first (by name), then its subfolders' (by path)."""
    return len(rel.parts) > 1, rel.parts


def _check_package(pkg: str, flag: str | None, configured: str | None, out: str | None, configured_out: str | None,
                   out_dir: Path, where: Path, prefix: str) -> None:
    """The generated package's name must be importable; the error points at what gave it."""
    if _DOTTED.fullmatch(pkg) and not any(part == "__pycache__" or keyword.iskeyword(part) for part in pkg.split(".")):
        return
    source = "--package" if flag else (f"{prefix}package" if configured else f"the folder name of out ({out_dir.name!r})")
    message = f"{prefix}package: {pkg!r} from {source} is not an importable name; set package"
    if not flag and not configured and not out and configured_out:  # the configured out's name
        raise CompileError([Diagnostic(Location(display(where), _key_line(where, f"{prefix}out"), 1), message)])
    if flag or not configured:  # from the command line or a folder name: no line of a file says it
        raise CompileError([Diagnostic(Location(display(out_dir), 1, 1), f"package: {pkg!r} from {source} is not "
                                                                         "an importable name; pass --package or set package")])
    raise _config_error(where, message)


def _exports(value: Any, root: Path, where: Path, prefix: str) -> tuple[ExportEntry, ...]:
    if value is None:
        return ()
    if not isinstance(value, list):
        raise _config_error(where, f"{prefix}exports: expected a list of tables ([[{prefix}exports]])")
    entries = []
    lines = _entry_lines(where, len(value))
    for item, line in zip(value, lines, strict=True):
        if not isinstance(item, dict) or not {"format", "model", "output"} <= set(item):
            raise _config_error(where, f"{prefix}exports: every entry needs format, model and output")
        extra = set(item) - {"format", "model", "output", "options"}
        if extra:
            raise _config_error(where, f"{prefix}exports: unknown key {sorted(extra)[0]!r} (format, model, output, options)")
        options = item.get("options", {})
        if not all(isinstance(item[k], str) for k in ("format", "model", "output")) or not isinstance(options, dict):
            raise _config_error(where, f"{prefix}exports: format, model and output are strings, options a table")
        entries.append(ExportEntry(item["format"], item["model"], root / item["output"], dict(options), line))
    return tuple(entries)


def _entry_lines(where: Path, count: int) -> list[int]:
    """The line of each ``[[tool.drivemap.exports]]`` header (or, for an inline list, of ``exports =``)."""
    header = "[[tool.drivemap.exports]]" if where.name == "pyproject.toml" else "[[exports]]"
    try:
        text = where.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return [1] * count
    found = [n for n, line in enumerate(text.splitlines(), 1) if line.strip().replace(" ", "") == header]
    if len(found) == count:
        return found
    return [_key_line(where, "exports")] * count

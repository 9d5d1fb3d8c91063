"""Reading users' YAML (Home Assistant, ESPHome): their tags kept as opaque values, every mapping with its line.

``!secret``, ``!include``, ``!lambda``, ``!env_var`` ... become :class:`Tagged` values (a field
holding one is not a stated fact); mappings are :class:`Node` dicts that know their line, so an
entry that cannot be imported is reported as ``file:line:col: error: ...``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from drivemap.diagnostics import CompileError, Diagnostic, Location
from drivemap.frontend.project import display

__all__ = ["Node", "Tagged", "here", "left_out", "load_yaml", "located", "renamed"]

_MAX_BYTES = 8 * 1024 * 1024


class Tagged(str):
    """A value behind a YAML tag (``!secret wifi``): its text, not a fact; where it stands, and the
    mapping behind a tag of a mapping (``!include {file: x.yaml, vars: {...}}``)."""

    tag: str = ""
    line: int = 1
    col: int = 1
    file: Path | None = None
    data: Any = None


class Node(dict[str, Any]):
    """A mapping that remembers where it starts (its file, 1-based line and column)."""

    line: int = 1
    col: int = 1
    file: Path | None = None


def renamed(node: Node, name: str) -> Node:
    """A copy of ``node`` with another ``name`` (and the same place in the file)."""
    out = Node(node, name=name)
    out.line, out.col, out.file = node.line, node.col, node.file
    return out


class _Loader(getattr(yaml, "CSafeLoader", yaml.SafeLoader)):  # type: ignore[misc]
    """libyaml's parser where it is installed (the pure-Python one is ten times slower)."""


class DuplicateKey(yaml.MarkedYAMLError):
    """A key given twice in one mapping (YAML says keys are unique; the last one would silently win)."""


def _mapping(loader: _Loader, node: yaml.MappingNode) -> Node:
    seen: dict[str, yaml.Node] = {}
    for key_node, _ in node.value:
        key = str(loader.construct_object(key_node, deep=True))
        if key in seen and key != "<<":
            first = seen[key].start_mark
            raise DuplicateKey(None, None, f"the key {key!r} is given twice in this mapping (first on line "
                                           f"{first.line + 1}): keep one", key_node.start_mark)
        seen[key] = key_node
    out = Node({str(k): v for k, v in loader.construct_mapping(node, deep=True).items()})
    out.line, out.col = node.start_mark.line + 1, node.start_mark.column + 1
    out.file = getattr(loader, "source", None)
    return out


def _tagged(loader: _Loader, suffix: str, node: yaml.Node) -> Tagged:
    value = loader.construct_scalar(node) if isinstance(node, yaml.ScalarNode) else ""
    out = Tagged(str(value))
    out.tag = "!" + suffix
    out.line, out.col = node.start_mark.line + 1, node.start_mark.column + 1
    out.file = getattr(loader, "source", None)
    if isinstance(node, yaml.MappingNode):
        out.data = _mapping(loader, node)
    elif isinstance(node, yaml.SequenceNode):
        out.data = loader.construct_sequence(node, deep=True)
    return out


_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _mapping)
_Loader.add_multi_constructor("!", _tagged)


def located(path: Path, where: Any, message: str) -> CompileError:
    """A located error at the mapping or tagged value ``where`` (in the file it was read from), else at
    the start of ``path``."""
    if isinstance(where, Node | Tagged):
        return CompileError([Diagnostic(Location(display(where.file or path), where.line, where.col), message)])
    return CompileError([Diagnostic(Location(display(path), 1, 1), message)])


def here(node: Any, path: Path) -> str:
    """``file:line`` of a mapping (the file it was read from), for review lines."""
    if isinstance(node, Node | Tagged):
        return f"{(node.file or path).name}:{node.line}"
    return path.name


def read_source(path: Path, max_bytes: int, too_large: str, encoding: str = "utf-8") -> str:
    """The text of a source file of at most ``max_bytes``; a located error (``too_large`` when it is
    larger) for a file that cannot be read or is not UTF-8."""
    shown = display(path)
    try:
        if path.stat().st_size > max_bytes:
            raise CompileError([Diagnostic(Location(shown, 1, 1), too_large)])
        return path.read_text(encoding=encoding)
    except OSError as exc:
        raise CompileError([Diagnostic(Location(shown, 1, 1), f"cannot read: {exc.strerror or exc}")]) from None
    except UnicodeDecodeError:
        raise CompileError([Diagnostic(Location(shown, 1, 1), "not UTF-8 text")]) from None


def load_yaml(path: Path) -> Any:
    """The document of ``path``; a located error for unreadable or malformed YAML."""
    shown = display(path)
    text = read_source(path, _MAX_BYTES, "larger than 8 MiB: not a configuration file")
    loader = _Loader(text)
    loader.source = path
    try:
        return loader.get_single_data()
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line, col = (mark.line + 1, mark.column + 1) if mark else (1, 1)
        said = exc.problem if isinstance(exc, DuplicateKey) else f"not YAML: {exc.problem or exc}"
        raise CompileError([Diagnostic(Location(shown, line, col), str(said))]) from None
    except (yaml.YAMLError, RecursionError) as exc:
        raise CompileError([Diagnostic(Location(shown, 1, 1), f"not YAML: {exc}")]) from None
    finally:
        loader.dispose()


def left_out(path: Path) -> list[str]:
    """The registers a drivemap export says it left out (its ``# not exported...`` comment lines), each
    as ``file:line: text``: the file cannot carry them, so the map built from it lacks them."""
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError):
        return []
    return [f"{path.name}:{n}: {line.lstrip()[2:]} (the export left it out: add it from the manual)"
            for n, line in enumerate(lines, 1) if line.lstrip().startswith("# not exported")]

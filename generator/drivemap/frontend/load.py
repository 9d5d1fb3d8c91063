"""Safe YAML loading that keeps a line/column for every node.

Anchors, aliases, merge keys, duplicate keys, non-string keys and tags other than the plain
YAML core types are refused: a map is data written by hand, and refusing these keeps alias
bombs and ambiguity out. The result is plain Python data plus a :class:`Positions` table.
"""

from __future__ import annotations

import os
import re
import stat
from dataclasses import dataclass, field
from typing import Any

import yaml
from yaml.nodes import MappingNode, Node, ScalarNode, SequenceNode

from drivemap.diagnostics import CompileError, Diagnostic, Location

#: Maps larger than this are refused while reading (bounded time and memory). A map of all 65,536
#: words of one table takes about 12 MiB; 32 MiB leaves room for two full tables with notes.
MAX_MAP_BYTES = 32 * 1024 * 1024
#: Deepest nesting accepted (checked on the parser's events, before anything recurses).
MAX_DEPTH = 40
#: Most YAML values (scalars, mappings, lists) a map may hold, counted on the parser's events before
#: anything is built: a register of the synthetic benchmark map takes about 25, so 65,536 registers
#: fit; what building costs is bounded by this, not by the file size (docs/limits.md).
MAX_NODES = 2_000_000
#: Most registers a map may hold (one full address space of one table), counted on the same events:
#: build time and memory grow with it (about 1 ms and 20 KB per register, docs/limits.md).
MAX_REGISTERS = 65_536
#: Largest integer magnitude accepted anywhere in a map (a 64-bit register's range fits).
MAX_INT = 2**64

PathT = tuple[str | int, ...]


@dataclass
class Positions:
    """Line/column of every value (and of every mapping key) in a loaded document."""

    path: str
    values: dict[PathT, tuple[int, int]] = field(default_factory=dict)
    keys: dict[PathT, tuple[int, int]] = field(default_factory=dict)
    #: the file of a value or key that comes from another file than ``path`` (a map that extends
    #: another: frontend.family), by path
    files: dict[PathT, str] = field(default_factory=dict)
    #: a value a variant inherits inside an item it overrides -> where the override is (a note on
    #: any error located at that value: the override may be what made it)
    overrides: dict[tuple[str, int, int], Location] = field(default_factory=dict)

    def at(self, where: PathT, *, key: bool = False) -> Location:
        """Location of the value at ``where`` (or of its key), falling back to the nearest parent."""
        table = self.keys if key else self.values
        probe = tuple(where)
        while probe:
            if probe in table:
                line, col = table[probe]
                return Location(self.files.get(probe, self.path), line, col)
            if probe in self.values:
                line, col = self.values[probe]
                return Location(self.files.get(probe, self.path), line, col)
            probe = probe[:-1]
        line, col = self.values.get((), (1, 1))
        return Location(self.path, line, col)


@dataclass
class Document:
    """A loaded map: its data and where each item stands in the file."""

    path: str
    data: Any
    positions: Positions


def _loc(path: str, node: Node) -> Location:
    mark = node.start_mark
    return Location(path, mark.line + 1, mark.column + 1)


class _Composer(yaml.SafeLoader):
    """SafeLoader that refuses anchors and aliases while composing."""

    def compose_node(self, parent: Node | None, index: Any) -> Node | None:
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()  # type: ignore[no-untyped-call]
            raise _Refused(event.start_mark, "aliases (*name) are not allowed in maps")
        event = self.peek_event()  # type: ignore[no-untyped-call]
        anchor = getattr(event, "anchor", None)
        if anchor is not None:
            raise _Refused(event.start_mark, f"anchors (&{anchor}) are not allowed in maps")
        node: Node | None = super().compose_node(parent, index)
        return node


class _Refused(Exception):
    def __init__(self, mark: Any, message: str) -> None:
        super().__init__(message)
        self.mark = mark
        self.message = message


#: A plain integer with a leading zero: YAML 1.1 (PyYAML) reads it as octal (00017 is 15), never what a
#: manual's "00017" means.
_OCTAL = re.compile(r"[-+]?0[0-7_]+")

_PLAIN_TAGS = {
    "tag:yaml.org,2002:str",
    "tag:yaml.org,2002:int",
    "tag:yaml.org,2002:float",
    "tag:yaml.org,2002:bool",
    "tag:yaml.org,2002:null",
    "tag:yaml.org,2002:map",
    "tag:yaml.org,2002:seq",
}


class _Builder:
    def __init__(self, path: str) -> None:
        self.path = path
        self.positions = Positions(path)
        self.errors: list[Diagnostic] = []
        self._constructor = yaml.SafeLoader("")

    def build(self, node: Node, where: PathT, depth: int = 0) -> Any:
        self.positions.values[where] = (node.start_mark.line + 1, node.start_mark.column + 1)
        if depth > MAX_DEPTH:
            self.errors.append(Diagnostic(_loc(self.path, node), f"nesting deeper than {MAX_DEPTH} levels"))
            return None
        if node.tag not in _PLAIN_TAGS:
            self.errors.append(Diagnostic(_loc(self.path, node), f"tag {node.tag!r} is not allowed in maps"))
            return None
        if isinstance(node, MappingNode):
            result: dict[str, Any] = {}
            first: dict[str, Node] = {}
            for key_node, value_node in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    self.errors.append(Diagnostic(_loc(self.path, key_node), "merge keys (<<) are not allowed in maps"))
                    continue
                if not isinstance(key_node, ScalarNode) or key_node.tag != "tag:yaml.org,2002:str":
                    self.errors.append(
                        Diagnostic(_loc(self.path, key_node), "mapping keys must be plain strings")
                    )
                    continue
                key = key_node.value
                if key in first:
                    self.errors.append(
                        Diagnostic(
                            _loc(self.path, key_node),
                            f"duplicate key {key!r}",
                            related=((_loc(self.path, first[key]), "first defined here"),),
                        )
                    )
                    continue
                first[key] = key_node
                self.positions.keys[where + (key,)] = (key_node.start_mark.line + 1, key_node.start_mark.column + 1)
                result[key] = self.build(value_node, where + (key,), depth + 1)
            return result
        if isinstance(node, SequenceNode):
            return [self.build(item, where + (i,), depth + 1) for i, item in enumerate(node.value)]
        assert isinstance(node, ScalarNode)
        if node.tag == "tag:yaml.org,2002:int" and not node.style and _OCTAL.fullmatch(node.value):
            self.errors.append(Diagnostic(_loc(self.path, node), f"{node.value} is an octal number in YAML 1.1 "
                                          f"({int(node.value.replace('_', ''), 8)}): write it without leading zeros, "
                                          f"or quote it (\"{node.value}\") for a Modicon number"))
            return None
        try:
            value = self._constructor.construct_object(node, deep=True)
        except (yaml.YAMLError, ValueError, OverflowError) as exc:
            self.errors.append(Diagnostic(_loc(self.path, node), f"bad scalar: {exc}"))
            return None
        if isinstance(value, int) and not isinstance(value, bool) and abs(value) > MAX_INT:
            self.errors.append(Diagnostic(_loc(self.path, node), "integer too large (more than 2**64 in magnitude)"))
            return None
        if isinstance(value, float) and (value != value or value in (float("inf"), float("-inf"))):
            self.errors.append(Diagnostic(_loc(self.path, node), "NaN and infinity are not allowed"))
            return None
        return value


def _check_depth(text: str, path: str) -> None:
    """Refuse nesting deeper than MAX_DEPTH from the parser's events (a state machine, no recursion),
    so neither libyaml's nor PyYAML's recursive composer ever sees a deep document."""
    loader_class = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    try:
        _depth_events(text, path, loader_class)
    except (yaml.YAMLError, ValueError):
        # libyaml refuses deep documents itself ("maximum nesting depth", wording by version), and
        # may do so while scanning ahead, before it hands over the events that would reach our
        # limit: the pure-Python parser (a state machine too) decides, so the message is always ours.
        if loader_class is not yaml.SafeLoader:
            try:
                _depth_events(text, path, yaml.SafeLoader)
            except (yaml.YAMLError, ValueError):
                pass
        return  # the composer reports syntax errors with their location


def _refuse(event: Any, path: str, message: str) -> CompileError:
    mark = event.start_mark
    line, col = (mark.line + 1, mark.column + 1) if mark is not None else (1, 1)
    return CompileError([Diagnostic(Location(path, line, col), message)])


class _Registers:
    """Counts the items of the top-level ``registers`` list on the parser's events."""

    def __init__(self) -> None:
        self.stack: list[list[Any]] = []  # [is_mapping, expecting_key, last key, is_the_registers_list]
        self.count = 0

    def item(self, event: Any) -> bool:
        """Note a value event; True when it is one register too many."""
        parent = self.stack[-1] if self.stack else None
        is_value = True
        if parent is not None and parent[0]:
            if parent[1]:
                parent[2] = getattr(event, "value", None)
                is_value = False
            parent[1] = not parent[1]
        elif parent is not None and parent[3]:
            self.count += 1
        if isinstance(event, (yaml.MappingStartEvent, yaml.SequenceStartEvent)):
            top = len(self.stack) == 1 and parent is not None and parent[0] and parent[2] == "registers"
            self.stack.append([isinstance(event, yaml.MappingStartEvent), True, None,
                               is_value and top and isinstance(event, yaml.SequenceStartEvent)])
        return self.count > MAX_REGISTERS


def _depth_events(text: str, path: str, loader_class: Any) -> None:
    depth = nodes = 0
    registers = _Registers()
    for event in yaml.parse(text, Loader=loader_class):
        if isinstance(event, (yaml.ScalarEvent, yaml.MappingStartEvent, yaml.SequenceStartEvent, yaml.AliasEvent)):
            nodes += 1
            if nodes > MAX_NODES:
                raise _refuse(event, path, f"more than {MAX_NODES:,} YAML values (scalars, mappings, lists): "
                                           "map refused before anything is built")
            if registers.item(event):
                raise _refuse(event, path, f"more than {MAX_REGISTERS:,} registers: map refused before anything "
                                           "is built (bounded time and memory; docs/limits.md)")
        elif isinstance(event, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
            registers.stack.pop()
        if isinstance(event, (yaml.MappingStartEvent, yaml.SequenceStartEvent)):
            depth += 1
            if depth > MAX_DEPTH:
                mark = event.start_mark
                line, col = (mark.line + 1, mark.column + 1) if mark is not None else (1, 1)
                raise CompileError([Diagnostic(Location(path, line, col), f"nesting deeper than {MAX_DEPTH} levels")])
        elif isinstance(event, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
            depth -= 1


def _compose_fast(text: str) -> Node | None:
    """Compose with libyaml when PyYAML has it; None when it cannot (the Python path then decides).

    Anchors and aliases are refused by a first pass over the parser's events, so the C composer
    never expands an alias. Any problem falls back to the Python path, which owns the messages.
    """
    loader_class = getattr(yaml, "CSafeLoader", None)
    if loader_class is None:
        return None
    try:
        for event in yaml.parse(text, Loader=loader_class):
            if isinstance(event, yaml.AliasEvent) or getattr(event, "anchor", None) is not None:
                return None
        loader = loader_class(text)
        try:
            node: Node | None = loader.get_single_node()
        finally:
            loader.dispose()
        return node
    except (yaml.YAMLError, RecursionError, ValueError):
        return None


def load_text(text: str, path: str) -> Document:
    """Parse ``text`` (the contents of ``path``); raise :class:`CompileError` on any problem."""
    if len(text.encode("utf-8", "surrogatepass")) > MAX_MAP_BYTES:
        raise CompileError([Diagnostic(Location(path, 1, 1), f"file larger than {MAX_MAP_BYTES} bytes; refused")])
    _check_depth(text, path)
    node = _compose_fast(text)
    if node is None:
        node = _compose_python(text, path)
    if node is None:
        raise CompileError([Diagnostic(Location(path, 1, 1), "empty file: a map is a YAML mapping")])
    builder = _Builder(path)
    data = builder.build(node, ())
    if builder.errors:
        raise CompileError(builder.errors)
    return Document(path, data, builder.positions)


def _compose_python(text: str, path: str) -> Node | None:
    """The pure-Python composer: refuses anchors and aliases, and locates every syntax error."""
    try:
        loader = _Composer(text)
    except yaml.reader.ReaderError as exc:
        line = text.count("\n", 0, exc.position) + 1
        col = exc.position - (text.rfind("\n", 0, exc.position) + 1) + 1
        raise CompileError([Diagnostic(Location(path, line, col), f"character {exc.character!r} is not allowed in YAML")]) from None
    try:
        node = loader.get_single_node()
    except _Refused as exc:
        raise CompileError([Diagnostic(Location(path, exc.mark.line + 1, exc.mark.column + 1), exc.message)]) from None
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line, col = (mark.line + 1, mark.column + 1) if mark else (1, 1)
        problem = exc.problem or exc.context or "invalid YAML"
        raise CompileError([Diagnostic(Location(path, line, col), f"YAML syntax error: {problem}")]) from None
    except yaml.reader.ReaderError as exc:
        line = text.count("\n", 0, exc.position) + 1
        col = exc.position - (text.rfind("\n", 0, exc.position) + 1) + 1
        raise CompileError([Diagnostic(Location(path, line, col), f"character {exc.character!r} is not allowed in YAML")]) from None
    except yaml.YAMLError as exc:
        raise CompileError([Diagnostic(Location(path, 1, 1), f"YAML error: {type(exc).__name__}")]) from None
    except RecursionError:
        raise CompileError([Diagnostic(Location(path, 1, 1), "YAML nested too deeply")]) from None
    finally:
        loader.dispose()
    return node


def read_map_text(path: str | os.PathLike[str]) -> str:
    """The text of a map file as it is on disk (line endings kept): regular files only, at most
    :data:`MAX_MAP_BYTES`, strict UTF-8; a located :class:`CompileError` otherwise."""
    shown = os.fspath(path)
    too_big = CompileError([Diagnostic(Location(shown, 1, 1), f"file larger than {MAX_MAP_BYTES} bytes; refused")])
    try:
        if not stat.S_ISREG(os.stat(shown).st_mode):
            raise CompileError([Diagnostic(Location(shown, 1, 1), "not a regular file (a FIFO, device or folder); refused")])
        if os.path.getsize(shown) > MAX_MAP_BYTES:
            raise too_big
        with open(shown, "rb") as handle:
            raw = handle.read(MAX_MAP_BYTES + 1)  # bounded even if the file grows while it is read
    except OSError as exc:
        raise CompileError([Diagnostic(Location(shown, 1, 1), f"cannot read file: {exc.strerror}")]) from None
    if len(raw) > MAX_MAP_BYTES:
        raise too_big
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        col = exc.start - (raw.rfind(b"\n", 0, exc.start) + 1) + 1
        raise CompileError([Diagnostic(Location(shown, line, col), "file is not valid UTF-8")]) from None


def load_file(path: str | os.PathLike[str]) -> Document:
    """Read and parse one map file."""
    return load_text(read_map_text(path), os.fspath(path))

"""Device families: a map that extends another (``extends:``) and says only what its model changes.

``extends`` names the base map: a file (``acme.yaml``, relative to the extending map) or a model id
(``acme``: ``acme.yaml`` in the same folder). The base may extend another map in turn; a cycle is
refused. A base map must be a regular file inside the project of the map that extends (the folder of
its ``pyproject.toml``/``drivemap.toml``; without one, the working directory's project when the map is
in it, else the map's own folder) or a map shipped with drivemap (``drivemap/data/maps`` and its
sub-folders): the real path counts, so neither ``../..`` nor a symbolic link leads out. The extending
map is laid over its base:

- ``device`` and ``protocol``: each key given replaces the base's; ``protocol.function_codes`` and
  ``protocol.exceptions`` merge item by item (by ``code``);
- ``registers``, ``groups``, ``examples`` (by ``name``), ``known_issues`` (by ``title``) and
  ``identity`` (by ``register``): an item of a name the base has replaces the keys it gives (a
  register that only changes ``max`` gives ``name`` and ``max``; an identity check is replaced
  whole); a new name is added at the end;
- ``enums`` (by name) replace the base's enum whole; ``reserved`` replaces the base's list whole;
- ``remove:`` lists what the base has and the variant drops (``registers``, ``groups``, ``examples``,
  ``enums`` and ``identity`` by name, ``known_issues`` by title, ``function_codes`` and ``exceptions``
  by code). Removing and then giving an item again replaces it whole.

The result is checked as one map; every value keeps the file and line it came from, so each error
points at the file that made it. :class:`~drivemap.model.family.Variant` lists what changed (docs).
"""

from __future__ import annotations

import copy
import dataclasses
import os
from pathlib import Path
from typing import Any

from drivemap.diagnostics import CompileError, Diagnostic, Location
from drivemap.frontend import formats
from drivemap.frontend.load import Document, PathT, Positions, load_file
from drivemap.frontend.project import find_project
from drivemap.model.family import Variant

MAX_CHAIN = 16
#: The maps shipped with drivemap (and the catalogue's, in sub-folders): a base anywhere under it is allowed.
SHIPPED_MAPS = Path(__file__).resolve().parent.parent / "data" / "maps"
#: keyed lists: top-level key -> the item key that names an item
KEYED = {"registers": "name", "groups": "name", "examples": "name", "known_issues": "title", "identity": "register"}
PROTOCOL_KEYED = {"function_codes": "code", "exceptions": "code"}
REMOVABLE = (*KEYED, "enums", "function_codes", "exceptions")
_SINGULAR = {"registers": "register", "groups": "group", "examples": "example", "known_issues": "known issue",
             "identity": "identity check", "enums": "enum", "function_codes": "function code",
             "exceptions": "exception"}


class _Index:
    """A document's positions, grouped by path prefix (grafting a subtree costs its own size)."""

    def __init__(self, doc: Document) -> None:
        self.doc = doc
        self.by_prefix: dict[PathT, list[PathT]] = {}
        for path in {*doc.positions.values, *doc.positions.keys}:
            for k in range(0, min(len(path), 4) + 1):
                self.by_prefix.setdefault(path[:k], []).append(path)

    def under(self, prefix: PathT) -> list[PathT]:
        if len(prefix) <= 4:
            return self.by_prefix.get(prefix, [])
        return [p for p in self.by_prefix.get(prefix[:4], []) if p[: len(prefix)] == prefix]


class _Merge:
    def __init__(self, variant: Document) -> None:
        self.positions = Positions(variant.path)
        self.changes: list[str] = []
        self.errors: list[Diagnostic] = []

    def graft(self, index: _Index, src: PathT, dst: PathT) -> None:
        """Copy the positions under ``src`` of ``index``'s document to ``dst`` (with its file)."""
        pos = index.doc.positions
        for path in index.under(src):
            new = dst + path[len(src):]
            if path in pos.values:
                self.positions.values[new] = pos.values[path]
            if path in pos.keys:
                self.positions.keys[new] = pos.keys[path]
            if index.doc.path != self.positions.path:
                self.positions.files[new] = pos.files.get(path, index.doc.path)
            else:
                self.positions.files.pop(new, None)


def resolve(doc: Document) -> tuple[Document, Variant | None]:
    """``doc`` laid over the maps it extends (itself when it extends none), and what it changes."""
    if isinstance(doc.data, dict) and "remove" in doc.data and "extends" not in doc.data:
        raise CompileError([Diagnostic(doc.positions.at(("remove",), key=True),
                                       "remove: only a map that extends another removes (give extends)")])
    if not isinstance(doc.data, dict) or "extends" not in doc.data:
        return doc, None
    chain = [doc]
    seen = [os.path.realpath(doc.path)]
    roots = allowed_roots(doc.path)
    while isinstance(chain[-1].data, dict) and "extends" in chain[-1].data:
        child = chain[-1]
        target = child.data["extends"]
        where = child.positions.at(("extends",))
        if not isinstance(target, str) or not target:
            return child, None  # the schema reports it
        path = _target_path(child.path, target)
        real = os.path.realpath(path)
        if real in seen:
            cycle = " -> ".join([*(Path(p).name for p in seen[seen.index(real):]), Path(real).name])
            raise CompileError([Diagnostic(where, f"extends makes a cycle: {cycle}")])
        if len(chain) > MAX_CHAIN:
            raise CompileError([Diagnostic(where, f"extends chain longer than {MAX_CHAIN} maps")])
        if not any(_inside(real, root) for root in roots) and not _inside(os.path.abspath(path), str(SHIPPED_MAPS)):
            raise CompileError([Diagnostic(where, f"extends {target!r}: {path} is outside the project ({roots[0]}); a "
                                                  "base map is a map of the project or one shipped with drivemap")])
        if not os.path.lexists(path):
            raise CompileError([Diagnostic(where, f"extends {target!r}: no map file {path}")])
        if not os.path.isfile(path):
            raise CompileError([Diagnostic(where, f"extends {target!r}: {path} is not a regular file (a FIFO, "
                                                  "device or folder); refused")])
        base = load_file(path)
        if not isinstance(base.data, dict):
            raise CompileError([Diagnostic(base.positions.at(()), "a map is a YAML mapping at the top level")])
        formats.upgrade(base)
        chain.append(base)
        seen.append(real)
    merged = chain[-1]
    changes: list[str] = []
    for child in reversed(chain[:-1]):
        merged, made = _lay_over(merged, child)
        changes = made
    return merged, Variant(tuple(d.path for d in chain[1:]), tuple(changes))


def allowed_roots(path: str) -> list[str]:
    """The real folder a base of the map at ``path`` may be in: its project's root (a path into the shipped
    maps is allowed as written: they may be links, into the source tree, in an editable install)."""
    folder = os.path.dirname(os.path.abspath(path))
    roots: list[str] = []
    try:
        root, config, _ = find_project(Path(folder))
        if config is not None:
            roots.append(os.path.realpath(root))
        else:
            here = os.path.realpath(find_project()[0])
            roots.append(here if _inside(os.path.realpath(path), here) else os.path.realpath(folder))
    except CompileError:  # an unreadable configuration on the way up: the map's own folder
        roots.append(os.path.realpath(folder))
    return roots


def _inside(real: str, root: str) -> bool:
    return real == root or real.startswith(root.rstrip(os.sep) + os.sep)


def _target_path(child: str, target: str) -> str:
    folder = os.path.dirname(child)
    name = target if target.endswith((".yaml", ".yml")) or "/" in target else f"{target}.yaml"
    return os.path.normpath(os.path.join(folder, name)) if folder else os.path.normpath(name)


def _lay_over(base: Document, child: Document) -> tuple[Document, list[str]]:
    """``child`` laid over ``base`` (both loaded documents); the merged document and its changes."""
    m = _Merge(child)
    bi, ci = _Index(base), _Index(child)
    data: dict[str, Any] = copy.deepcopy(base.data)
    data.pop("extends", None)
    m.graft(bi, (), ())
    removed = _remove(m, data, child)
    for key, value in child.data.items():
        if key in ("extends", "remove"):
            continue
        if key in KEYED and isinstance(value, list) and isinstance(data.get(key), list):
            _merge_list(m, bi, ci, data, (key,), value, KEYED[key])
        elif key in ("device", "protocol") and isinstance(value, dict) and isinstance(data.get(key), dict):
            _merge_section(m, bi, ci, data, key, value)
        elif key == "enums" and isinstance(value, dict) and isinstance(data.get(key), dict):
            for name, enum in value.items():
                m.changes.append(f"enum {name}: {'replaced' if name in data[key] else 'added'}")
                data[key][name] = copy.deepcopy(enum)
                m.graft(ci, (key, name), (key, name))
        else:
            if key not in ("drivemap",):
                m.changes.append(f"{key}: replaced" if key in data else f"{key}: added")
            data[key] = copy.deepcopy(value)
            _drop(m, (key,))
            m.graft(ci, (key,), (key,))
    m.positions.overrides.update({k: v for k, v in base.positions.overrides.items()})
    m.positions.values[()] = child.positions.values.get((), (1, 1))
    m.positions.files.pop((), None)
    if m.errors:
        raise CompileError(m.errors)
    return Document(child.path, data, m.positions), [*removed, *m.changes]


def _drop(m: _Merge, prefix: PathT) -> None:
    for table in (m.positions.values, m.positions.keys):
        for path in [p for p in table if p[: len(prefix)] == prefix]:
            del table[path]


def _merge_section(m: _Merge, bi: _Index, ci: _Index, data: dict[str, Any], key: str, value: dict[str, Any]) -> None:
    for sub, item in value.items():
        if key == "protocol" and sub in PROTOCOL_KEYED and isinstance(item, list) and isinstance(data[key].get(sub), list):
            _merge_list(m, bi, ci, data, (key, sub), item, PROTOCOL_KEYED[sub])
            continue
        if key == "device" and sub == "model":
            data[key][sub] = item
        elif data[key].get(sub) != item:
            m.changes.append(f"{key}.{sub}: {'changed' if sub in data[key] else 'added'}")
        data[key][sub] = copy.deepcopy(item)
        m.graft(ci, (key, sub), (key, sub))


def _merge_list(m: _Merge, bi: _Index, ci: _Index, data: dict[str, Any], where: PathT, items: list[Any], ident: str) -> None:
    target: list[Any] = data[str(where[0])] if len(where) == 1 else data[str(where[0])][str(where[1])]
    label = _SINGULAR.get(str(where[-1]), str(where[-1]))
    for j, item in enumerate(items):
        if not isinstance(item, dict) or ident not in item:
            m.errors.append(Diagnostic(ci.doc.positions.at((*where, j)), f"{label} in a map that extends another needs its {ident}"))
            continue
        name = item[ident]
        i = next((k for k, old in enumerate(target) if isinstance(old, dict) and old.get(ident) == name), None)
        if i is None:
            target.append(copy.deepcopy(item))
            m.graft(ci, (*where, j), (*where, len(target) - 1))
            m.changes.append(f"{label} {_show(name)}: added")
            continue
        if where == ("identity",):  # a check is replaced whole (equals and one_of exclude each other)
            target[i] = copy.deepcopy(item)
            _drop(m, (*where, i))
            m.graft(ci, (*where, j), (*where, i))
            m.changes.append(f"{label} {_show(name)}: replaced")
            continue
        keys = [k for k in item if k != ident and target[i].get(k) != item[k]]
        for k in item:
            target[i][k] = copy.deepcopy(item[k])
            _drop(m, (*where, i, k))
            m.graft(ci, (*where, j, k), (*where, i, k))
        m.positions.values[(*where, i)] = ci.doc.positions.values[(*where, j)]
        m.positions.files.pop((*where, i), None)
        m.changes.append(f"{label} {_show(name)}: {', '.join(keys) or 'nothing'} changed")
        _note_inherited(m, (*where, i), ci.doc.positions.at((*where, j)))


def _note_inherited(m: _Merge, item: PathT, override: Location) -> None:
    """Values of an overridden item that still come from the base: an error there notes the override."""
    n = len(item)
    for path in [p for p in m.positions.files if p[:n] == item]:
        for table in (m.positions.values, m.positions.keys):
            if path in table:
                line, col = table[path]
                m.positions.overrides[(m.positions.files[path], line, col)] = override


def _show(name: Any) -> str:
    return f"0x{name:02X}" if isinstance(name, int) else str(name)


def _remove(m: _Merge, data: dict[str, Any], child: Document) -> list[str]:
    """Apply the child's ``remove:`` to ``data`` (positions are re-indexed)."""
    spec = child.data.get("remove")
    if not isinstance(spec, dict):
        return []  # absent, or the schema reports it
    done = []
    for key, names in spec.items():
        if key not in REMOVABLE or not isinstance(names, list):
            continue
        where: PathT = ("protocol", key) if key in PROTOCOL_KEYED else (key,)
        for j, name in enumerate(names):
            if not _remove_one(m, data, where, key, name):
                m.errors.append(Diagnostic(child.positions.at(("remove", key, j)),
                                           f"remove: the base map has no {_SINGULAR[key]} {_show(name)!s}"))
            else:
                done.append(f"{_SINGULAR[key]} {_show(name)}: removed")
    return done


def _remove_one(m: _Merge, data: dict[str, Any], where: PathT, key: str, name: Any) -> bool:
    container: Any = data
    for part in where:
        container = container.get(part) if isinstance(container, dict) else None
    if key == "enums":
        if not isinstance(container, dict) or name not in container:
            return False
        del container[name]
        _drop(m, (*where, name))
        return True
    ident = KEYED.get(key) or PROTOCOL_KEYED[key]
    if not isinstance(container, list):
        return False
    i = next((k for k, old in enumerate(container) if isinstance(old, dict) and old.get(ident) == name), None)
    if i is None:
        return False
    del container[i]
    _shift(m, where, i)
    return True


def _shift(m: _Merge, where: PathT, removed: int) -> None:
    """Positions of a list after its item ``removed`` was deleted: later items move up by one."""
    n = len(where)
    tables: tuple[dict[PathT, Any], ...] = (m.positions.values, m.positions.keys, m.positions.files)
    for table in tables:
        moved: dict[PathT, Any] = {}
        for path in [p for p in table if p[:n] == where and len(p) > n and isinstance(p[n], int)]:
            index = path[n]
            assert isinstance(index, int)
            if index < removed:
                continue
            value = table.pop(path)
            if index > removed:
                moved[(*where, index - 1, *path[n + 1:])] = value
        table.update(moved)




def note_overrides(doc: Document, diagnostics: list[Diagnostic]) -> list[Diagnostic]:
    """Each diagnostic at a value a variant inherits inside an item it overrides, with a note at the
    override (the error may come from the pair)."""
    table = doc.positions.overrides
    if not table:
        return diagnostics
    out = []
    for d in diagnostics:
        loc = d.location
        override = table.get((loc.path, loc.line, loc.col))
        if override is not None:
            d = dataclasses.replace(d, related=(*d.related, (override, "the item is overridden here (the value above is inherited from the base)")))
        out.append(d)
    return out


__all__ = ["note_overrides", "resolve"]

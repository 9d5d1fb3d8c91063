"""ESPHome's ``packages:`` and ``substitutions:``, applied as ESPHome applies them before it reads components.

Each local package (a mapping, usually ``!include``d) is merged under the configuration in order:
mappings merge key by key (the configuration's own value wins), lists are the package's items followed
by the configuration's (``sensor:`` of a package and of the device add up). A package's own
``packages:`` are merged first. A remote package (``url:`` / ``github://``) is not downloaded: it is
listed for review, with what to do. Then ``substitutions:`` (the packages' and the configuration's, the
latter winning) are substituted everywhere.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from drivemap.onboard.importers.mapdoc import Review
from drivemap.onboard.importers.substitutions import substitute
from drivemap.onboard.importers.yamlsrc import Node, here, located

__all__ = ["expand"]

_MAX_DEPTH = 20


def expand(data: Any, path: Path, review: Review) -> Any:
    """The configuration with its packages merged and its substitutions applied."""
    if not isinstance(data, dict):
        return data
    data = _packages(data, path, review, 0)
    variables = data.pop("substitutions", None) or {}
    if not isinstance(variables, dict):
        raise located(path, data, "substitutions: a mapping of names to values")
    unknown: list[str] = []
    data = substitute(data, {str(k): v for k, v in variables.items()}, path, unknown)
    review.notes.extend(dict.fromkeys(unknown))
    return data


def _packages(data: dict[str, Any], path: Path, review: Review, depth: int) -> dict[str, Any]:
    packages = data.get("packages")
    if packages is None:
        return data
    if depth > _MAX_DEPTH:
        raise located(path, data, f"packages nested more than {_MAX_DEPTH} deep")
    rest = Node({k: v for k, v in data.items() if k != "packages"})
    if isinstance(data, Node):
        rest.line, rest.col, rest.file = data.line, data.col, data.file
    items = list(packages.items()) if isinstance(packages, dict) else list(enumerate(packages or []))
    merged: Any = Node()
    for name, package in items:
        if isinstance(package, str) or (isinstance(package, dict) and "url" in package):
            where = here(packages, path) if isinstance(packages, Node) else path.name
            review.skipped.append(f"{where}: remote package {name!r} ({package if isinstance(package, str) else package['url']}): "
                                  "not downloaded; save its files beside the configuration and !include them")
            continue
        if not isinstance(package, dict):
            raise located(path, packages, f"packages: {name!r} is not a configuration (a mapping, or !include FILE)")
        merged = _merge(merged, _packages(package, path, review, depth + 1))
    return dict(_merge(merged, rest)) if not isinstance(data, Node) else _node(_merge(merged, rest), data)


def _node(value: Any, like: Node) -> Node:
    out = Node(value)
    out.line, out.col, out.file = like.line, like.col, like.file
    return out


def _merge(old: Any, new: Any) -> Any:
    if isinstance(new, dict) and isinstance(old, dict):
        out: dict[str, Any] = _node(old, old) if isinstance(old, Node) else dict(old)
        for key, value in new.items():
            out[key] = _merge(old[key], value) if key in old else value
        return out
    if isinstance(new, list) and isinstance(old, list):
        return [*old, *new]
    return new

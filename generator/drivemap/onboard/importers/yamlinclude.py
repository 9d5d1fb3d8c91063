"""Users' configurations as Home Assistant and ESPHome read them: ``!include`` resolved, ``!secret`` named.

* ``!include FILE`` (and ESPHome's ``!include {file: FILE, vars: {...}}``), ``!include_dir_named``,
  ``!include_dir_list``, ``!include_dir_merge_named``, ``!include_dir_merge_list``: read relative to the
  file that says it, and only inside the folder of the file given on the command line (its tree): a
  configuration cannot make the import read ``/etc`` or ``../..``. A missing file, a file outside that
  tree and an include cycle are located errors at the tag.
* ``!secret NAME`` stays a :class:`~.yamlsrc.Tagged` value: ``secrets.yaml`` is never opened; the
  import names the secret in its review (a field holding one is not a stated fact).
* ``!env_var``, ``!lambda`` and other tags stay tagged values as well.

Every mapping keeps the file and line it was read from, so an error in an included file names that file.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from drivemap.onboard.importers.substitutions import substitute
from drivemap.onboard.importers.yamlsrc import Node, Tagged, load_yaml, located

__all__ = ["Found", "load_config"]

_MAX_FILES = 500
_MAX_BYTES = 32 << 20
_DIR_TAGS = ("!include_dir_named", "!include_dir_list", "!include_dir_merge_named", "!include_dir_merge_list")


@dataclass
class Found:
    """What resolving a configuration met: the files read, the secrets named (never read)."""

    root: Path
    files: list[Path] = field(default_factory=list)
    size: int = 0
    secrets: list[str] = field(default_factory=list)


def load_config(path: Path) -> tuple[Any, Found]:
    """The document of ``path`` with every include resolved (see the module's text)."""
    found = Found(path.resolve().parent)
    return _load(path, found, ()), found


def _load(path: Path, found: Found, chain: tuple[Path, ...]) -> Any:
    found.files.append(path)
    if len(found.files) > _MAX_FILES:
        raise located(path, None, f"more than {_MAX_FILES} included files: not a device configuration")
    try:
        found.size += path.stat().st_size
    except OSError:
        pass  # load_yaml says why it cannot be read
    if found.size > _MAX_BYTES:
        raise located(path, None, f"the configuration and its includes are larger than {_MAX_BYTES >> 20} MiB: "
                                  "not a device configuration")
    return _resolve(load_yaml(path), path, found, (*chain, path.resolve()))


def _resolve(value: Any, path: Path, found: Found, chain: tuple[Path, ...]) -> Any:
    if isinstance(value, Tagged):
        return _tag(value, path, found, chain)
    if isinstance(value, Node):
        for key in list(value):
            value[key] = _resolve(value[key], path, found, chain)
        return value
    if isinstance(value, dict):
        return {k: _resolve(v, path, found, chain) for k, v in value.items()}
    if isinstance(value, list):
        return [_resolve(v, path, found, chain) for v in value]
    return value


def _tag(value: Tagged, path: Path, found: Found, chain: tuple[Path, ...]) -> Any:
    if value.tag == "!secret":
        found.secrets.append(f"{(value.file or path).name}:{value.line}: !secret {value} (named, not read)")
        return value
    if value.tag == "!include":
        spec = value.data if isinstance(value.data, dict) else {"file": str(value)}
        target = _inside(value, path, found, str(spec.get("file", "")))
        if target in chain:
            raise located(path, value, f"!include {target.name}: an include cycle ({' -> '.join(p.name for p in chain)})")
        data = _load(target, found, chain)
        variables = spec.get("vars")
        if isinstance(variables, dict) and variables:
            data = substitute(data, {str(k): v for k, v in variables.items()}, target)
        return data
    if value.tag in _DIR_TAGS:
        folder = _inside(value, path, found, str(value), folder=True)
        files = sorted(p for p in folder.rglob("*.yaml") if not any(x.startswith(".") for x in p.relative_to(folder).parts))
        loaded = [(p, _load(p, found, chain)) for p in files if p.resolve() not in chain]
        if value.tag == "!include_dir_named":
            return {p.stem: data for p, data in loaded}
        if value.tag == "!include_dir_list":
            return [data for _, data in loaded]
        if value.tag == "!include_dir_merge_list":
            return [item for _, data in loaded for item in (data if isinstance(data, list) else [])]
        merged: dict[str, Any] = {}
        for _, data in loaded:
            merged.update(data if isinstance(data, dict) else {})
        return merged
    return value


def _inside(value: Tagged, path: Path, found: Found, name: str, folder: bool = False) -> Path:
    """The file (or folder) a tag names, relative to the file that says it and inside the tree."""
    if not name:
        raise located(path, value, f"{value.tag} names no file")
    target = ((value.file or path).parent / name).resolve()
    if target != found.root and found.root not in target.parents:
        raise located(path, value, f"{value.tag} {name}: outside {found.root} (the folder of the file imported; "
                                   "includes are read only inside it): copy the file into that folder")
    if folder and not target.is_dir():
        raise located(path, value, f"{value.tag} {name}: no such folder")
    if not folder and not target.is_file():
        raise located(path, value, f"{value.tag} {name}: no such file")
    return target

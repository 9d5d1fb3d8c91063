"""Writing output that drivemap owns, and only that.

Every output folder keeps a manifest (``.drivemap-manifest.json``: each file drivemap wrote there,
with its SHA-256). The rules, checked for the whole set of files *before* anything is written:

- a file drivemap is about to write that exists but is not in the manifest is someone else's:
  error, nothing written (identical content is adopted: nothing is lost);
- a file in the manifest is drivemap's (its header says "do not edit"): it is rewritten even if it
  was changed by hand, and the change reports that it was;
- with ``prune`` (``drivemap build``), files of the manifest that no map produces any more are
  deleted, and nothing else ever is; a non-empty folder without a manifest is refused unless
  ``force`` (and even then files drivemap does not produce are kept).

Writing is staged: every new file goes to a temporary file next to its target first; only when
all are written are they renamed into place (each rename atomic), with the manifest recording
every old and new file while that happens, so an interrupted build leaves the previous output
intact or a state the next build recognises as its own.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from drivemap.diagnostics import CompileError, Diagnostic, Location
from drivemap.frontend.project import display

__all__ = ["MANIFEST", "Change", "check", "plan", "write", "write_single"]

MANIFEST = ".drivemap-manifest.json"
TMP_PREFIX = ".drivemap-tmp-"
VERSION = 1


def digest(text: str | bytes) -> str:
    data = text.encode("utf-8") if isinstance(text, str) else text
    return hashlib.sha256(data).hexdigest()


@dataclass
class Change:
    """What writing a set of files into one folder does (computed before anything is written)."""

    root: Path
    write: dict[str, str] = field(default_factory=dict)      # relative path -> new text
    unchanged: list[str] = field(default_factory=list)
    delete: list[str] = field(default_factory=list)
    edited: list[str] = field(default_factory=list)          # drivemap's files changed by hand, replaced
    files: dict[str, str] = field(default_factory=dict)      # the manifest afterwards
    errors: list[Diagnostic] = field(default_factory=list)

    @property
    def changed(self) -> int:
        return len(self.write) + len(self.delete)


def _error(path: Path, message: str) -> Diagnostic:
    return Diagnostic(Location(display(path), 1, 1), message)


def read_manifest(root: Path) -> dict[str, set[str]] | None:
    """relative path -> accepted hashes, or None when the folder has no manifest."""
    path = root / MANIFEST
    if not path.exists():
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        files = data["files"]
        pending = data.get("pending", {})
        if data.get("version") != VERSION or not isinstance(files, dict) or not isinstance(pending, dict):
            raise ValueError("unknown manifest layout")
        out: dict[str, set[str]] = {str(k): {str(v)} for k, v in files.items()}
        for k, v in pending.items():
            out.setdefault(str(k), set()).add(str(v))
        return out
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise CompileError([_error(path, f"unreadable drivemap manifest ({exc}); fix or remove it")]) from None


def _safe_rel(rel: str) -> bool:
    parts = Path(rel).parts
    return bool(parts) and not Path(rel).is_absolute() and ".." not in parts and parts[-1] != MANIFEST


def _content(path: Path) -> bytes | None:
    """A regular file's bytes (None when it does not exist); refuses links, folders and devices."""
    if not os.path.lexists(path):
        return None
    if path.is_symlink() or not path.is_file():
        raise IsADirectoryError(path)
    return path.read_bytes()


def plan(root: Path, outputs: Mapping[str, str], *, prune: bool, force: bool = False) -> Change:
    """The change that writing ``outputs`` (relative path -> text) into ``root`` makes."""
    change = Change(root)
    manifest = read_manifest(root)
    known = manifest or {}
    if prune and manifest is None and root.is_dir() and any(p.name != MANIFEST for p in root.iterdir()) and not force:
        change.errors.append(_error(root, "output folder is not empty and has no drivemap manifest: not building "
                                          "into it (pass --force to build there; files drivemap does not produce are kept)"))
        return change
    for rel, text in sorted(outputs.items()):
        if not _safe_rel(rel):
            change.errors.append(_error(root / rel, "output path leaves the output folder"))
            continue
        path = root / rel
        try:
            new = digest(text)
        except UnicodeEncodeError as exc:  # nothing is written: checked for every file before any is staged
            change.errors.append(_error(path, f"cannot be stored as UTF-8: character U+{ord(text[exc.start]):04X} "
                                              f"at offset {exc.start} (a lone surrogate)"))
            continue
        try:
            old = _content(path)
        except IsADirectoryError:
            change.errors.append(_error(path, "exists and is not a regular file; not overwritten"))
            continue
        change.files[rel] = new
        if old is None:
            change.write[rel] = text
        elif digest(old) == new:
            change.unchanged.append(rel)
        elif rel not in known:
            change.errors.append(_error(path, "exists and was not written by drivemap: not overwritten "
                                              "(move it away, or choose another output folder)"))
        else:
            change.write[rel] = text
            if digest(old) not in known[rel]:
                change.edited.append(rel)
    if prune:
        for rel in sorted(set(known) - set(outputs)):
            path = root / rel
            if not _safe_rel(rel):
                continue
            if path.is_file() and not path.is_symlink():
                change.delete.append(rel)
    else:
        for rel, hashes in known.items():
            if rel not in change.files and (root / rel).exists():
                change.files[rel] = sorted(hashes)[0]
    return change


def _write_manifest(root: Path, files: Mapping[str, str], pending: Mapping[str, str] | None = None) -> None:
    data = {"version": VERSION, "generator": "drivemap", "files": dict(sorted(files.items()))}
    if pending:
        data["pending"] = dict(sorted(pending.items()))
    _atomic_write(root / MANIFEST, json.dumps(data, indent=1) + "\n")


def _file_mode(target: Path) -> int:
    """The mode a new file gets from the umask (mkstemp's 0600 is not what users expect), or the
    mode of the file it replaces."""
    try:
        return target.stat().st_mode & 0o777
    except OSError:
        mask = os.umask(0o022)
        os.umask(mask)
        return 0o666 & ~mask


def _stage(target: Path, text: str) -> str:
    """Write ``text`` to a temporary file next to ``target``; return its path."""
    fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=TMP_PREFIX)
    try:
        os.fchmod(fd, _file_mode(target))
        with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as handle:
            handle.write(text)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    return tmp


def _atomic_write(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = _stage(path, text)
    try:
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def _sweep_temporaries(root: Path) -> None:
    """Temporary files a killed run left behind (only drivemap's own, by name)."""
    if root.is_dir():
        for tmp in root.rglob(f"{TMP_PREFIX}*"):
            if tmp.is_file() and not tmp.is_symlink():
                tmp.unlink()


def write(change: Change) -> None:
    """Carry out a planned change: stage every file, then rename them all, then prune."""
    if change.errors:
        raise CompileError(change.errors)
    root = change.root
    _sweep_temporaries(root)
    if not change.write and not change.delete and (root / MANIFEST).exists() and read_manifest(root) == {
        k: {v} for k, v in change.files.items()
    }:
        return
    staged: list[tuple[str, str]] = []
    try:
        for rel, text in sorted(change.write.items()):
            target = root / rel
            target.parent.mkdir(parents=True, exist_ok=True)
            staged.append((_stage(target, text), rel))
    except BaseException:
        for tmp, _ in staged:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
        raise
    old = {k: sorted(v)[0] for k, v in (read_manifest(root) or {}).items()}
    _write_manifest(root, old, pending={rel: change.files[rel] for _, rel in staged})
    for tmp, rel in staged:
        os.replace(tmp, root / rel)
    for rel in change.delete:
        _remove(root, rel)
    _write_manifest(root, change.files)


def _remove(root: Path, rel: str) -> None:
    path = root / rel
    with contextlib.suppress(FileNotFoundError):
        path.unlink()
    if path.suffix == ".py":
        cache = path.parent / "__pycache__"
        for compiled in cache.glob(f"{path.stem}.*.pyc") if cache.is_dir() else ():
            compiled.unlink()
        with contextlib.suppress(OSError):
            cache.rmdir()
    folder = path.parent
    while folder != root and root in folder.parents:
        try:
            folder.rmdir()
        except OSError:
            break
        folder = folder.parent


def check(root: Path, outputs: Mapping[str, str]) -> list[tuple[str, str]]:
    """(path relative to root, why) for every file ``write`` would change in ``root``."""
    stale = []
    known = read_manifest(root) or {}
    for rel, text in sorted(outputs.items()):
        path = root / rel
        if not path.is_file():
            stale.append((rel, "missing"))
        elif path.read_bytes() != text.encode("utf-8"):
            stale.append((rel, "differs"))
    for rel in sorted(set(known) - set(outputs)):
        if (root / rel).exists():
            stale.append((rel, "no map produces it any more (build deletes it)"))
    return stale


#: What every drivemap export that can carry a comment says in its first lines.
GENERATED_MARK = "generated by drivemap"


def write_single(target: Path, text: str, *, force: bool = False) -> list[Diagnostic]:
    """Write one file (``drivemap export -o FILE``) and nothing beside it (no manifest).

    An existing ``target`` is replaced only when drivemap wrote it (its first lines say
    "generated by drivemap", or a manifest of its folder lists it), when it already holds ``text``,
    or with ``force``; otherwise it is someone else's: an error, nothing written. The write is
    atomic (a temporary file renamed into place).
    """
    try:
        old = _content(target)
    except IsADirectoryError:
        return [_error(target, "exists and is not a regular file; not overwritten")]
    if old is not None and old != text.encode("utf-8") and not force:
        ours = GENERATED_MARK.encode() in old[:4000]
        try:
            ours = ours or target.name in (read_manifest(target.parent) or {})
        except CompileError:
            pass
        if not ours:
            return [_error(target, "exists and was not written by drivemap: not overwritten (pass --force to "
                                   "replace it, or choose another file)")]
    if old is None or old != text.encode("utf-8"):
        _atomic_write(target, text)
    return []

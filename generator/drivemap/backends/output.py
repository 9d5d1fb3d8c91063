"""Writing output that drivemap owns, and only that.

Every output folder keeps a manifest (``.drivemap-manifest.json``: each file drivemap wrote there,
with its SHA-256). The rules, checked for the whole set of files *before* anything is written:

- a file drivemap is about to write that exists but is not in the manifest is someone else's:
  error, nothing written (identical content is adopted: nothing is lost);
- a file in the manifest is drivemap's (its header says "do not edit"): it is rewritten even if it
  was changed by hand, and the change reports that it was;
- with ``prune`` (``drivemap build``), files of the manifest that no map produces any more are
  deleted when their content is still what drivemap wrote (its SHA-256 is in the manifest); one
  edited by hand, or replaced by another file, is kept and named; nothing else is ever deleted; a
  non-empty folder without a manifest is refused unless ``force`` (and even then files drivemap
  does not produce are kept);
- symbolic links are never followed for writing or deleting: a link anywhere on an output path is
  an error naming the link, and every output path must resolve inside the output folder.

The caller holds :func:`staging.locked` on the folder around ``plan`` and ``write`` (one build
per folder at a time). Writing is staged: every new file goes to a temporary file next to its
target first (recorded before it is created, see :mod:`drivemap.backends.staging`); only when
all are written are they renamed into place (each rename atomic), with the manifest recording
every old and new file while that happens, so an interrupted build leaves the previous output
intact or a state the next build recognises as its own.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import os
import secrets
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from drivemap.backends import staging
from drivemap.backends.staging import TMP_PREFIX, link_in, locked
from drivemap.diagnostics import CompileError, Diagnostic, Location
from drivemap.frontend.project import display

__all__ = ["MANIFEST", "TMP_PREFIX", "Change", "check", "locked", "plan", "settled", "write", "write_single"]

MANIFEST = ".drivemap-manifest.json"
VERSION = 1
#: Files of drivemap's own bookkeeping in an output folder (never "someone else's").
OWN = {MANIFEST, staging.JOURNAL, staging.LOCK}


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
    kept: list[str] = field(default_factory=list)            # no longer produced, but edited by hand: kept
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
    if prune and manifest is None and root.is_dir() and any(p.name not in OWN for p in root.iterdir()) and not force:
        change.errors.append(_error(root, "output folder is not empty and has no drivemap manifest: not building "
                                          "into it (pass --force to build there; files drivemap does not produce are kept)"))
        return change
    for rel, text in sorted(outputs.items()):
        if not _safe_rel(rel):
            change.errors.append(_error(root / rel, "output path leaves the output folder"))
            continue
        path = root / rel
        if _leaves(root, rel, change):
            continue
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
        _prune(root, known, outputs, change)
    else:
        for rel, hashes in known.items():
            if rel not in change.files and (root / rel).exists():
                change.files[rel] = sorted(hashes)[0]
    return change


def _leaves(root: Path, rel: str, change: Change) -> bool:
    """Record an error when ``root / rel`` goes through a symbolic link or resolves outside ``root``."""
    link = link_in(root, rel)
    if link is not None and link != root / rel:
        change.errors.append(_error(link, f"is a symbolic link (to {os.readlink(link)}): drivemap never writes or "
                                          "deletes through links; replace it with a folder or choose another output folder"))
        return True
    if link is None and not (root / rel).resolve().is_relative_to(root.resolve()):
        change.errors.append(_error(root / rel, "output path leaves the output folder"))
        return True
    return False


def _prune(root: Path, known: Mapping[str, set[str]], outputs: Mapping[str, str], change: Change) -> None:
    """Files of the manifest no map produces any more: deleted while they still hold what drivemap
    wrote, kept (and named) otherwise."""
    for rel in sorted(set(known) - set(outputs)):
        path = root / rel
        if not _safe_rel(rel) or not os.path.lexists(path) or _leaves(root, rel, change):
            continue
        if path.is_symlink() or not path.is_file():
            change.kept.append(rel)
            continue
        try:
            same = digest(path.read_bytes()) in known[rel]
        except OSError:
            same = False
        (change.delete if same else change.kept).append(rel)


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


def _stage(target: Path, text: str, tmp: Path) -> str:
    """Write ``text`` to the temporary file ``tmp`` next to ``target`` (never an existing file or a
    link); return its path."""
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o600)
    try:
        os.fchmod(fd, _file_mode(target))
        with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as handle:
            handle.write(text)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    return str(tmp)


def _atomic_write(path: Path, text: str) -> None:
    """The manifest, through a staging file of a fixed name the next build recognises."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = _stage(path, text, path.parent / f"{TMP_PREFIX}manifest")
    try:
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def settled(change: Change) -> bool:
    """Whether :func:`write` would change nothing in ``change.root``: nothing to write or delete, the
    manifest already the one it would write, and no staging file of an interrupted build left."""
    root = change.root
    if change.write or change.delete or not (root / MANIFEST).is_file():
        return False
    if any(os.path.lexists(root / name) for name in (staging.JOURNAL, f"{TMP_PREFIX}journal", f"{TMP_PREFIX}manifest")):
        return False
    try:
        return read_manifest(root) == {k: {v} for k, v in change.files.items()}
    except CompileError:
        return False


def write(change: Change) -> None:
    """Carry out a planned change: stage every file, then rename them all, then prune (nothing at all
    when the change is :func:`settled`: no file or folder is touched)."""
    if change.errors:
        raise CompileError(change.errors)
    root = change.root
    if root.is_dir():
        staging.sweep(root)
    if settled(change):
        return
    token = secrets.token_hex(6)
    names = {rel: (Path(rel).parent / f"{TMP_PREFIX}{token}-{i}").as_posix() for i, rel in enumerate(sorted(change.write))}
    if names:
        root.mkdir(parents=True, exist_ok=True)
        staging.record(root, names.values())
    staged: list[tuple[str, str]] = []
    try:
        for rel, text in sorted(change.write.items()):
            target = root / rel
            target.parent.mkdir(parents=True, exist_ok=True)
            staged.append((_stage(target, text, root / names[rel]), rel))
    except BaseException:
        for tmp, _ in staged:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
        staging.forget(root)
        raise
    old = {k: sorted(v)[0] for k, v in (read_manifest(root) or {}).items()}
    _write_manifest(root, old, pending={rel: change.files[rel] for _, rel in staged})
    for tmp, rel in staged:
        os.replace(tmp, root / rel)
    for rel in change.delete:
        _remove(root, rel)
    _write_manifest(root, change.files)
    staging.forget(root)


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
        path = root / rel
        if path.is_file() and not path.is_symlink():
            same = digest(path.read_bytes()) in known[rel]
            stale.append((rel, "no map produces it any more (build deletes it)" if same else
                          "no map produces it any more (build keeps it: edited by hand)"))
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
        return _write_alone(target, text)
    return []


def _write_alone(target: Path, text: str) -> list[Diagnostic]:
    """``text`` into ``target`` through a temporary file beside it, renamed into place (nothing else
    stays behind); a folder that cannot hold it, or a name the system refuses, is a located error."""
    folder = target.parent
    try:
        folder.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=f".{target.name[:40]}.", suffix=".drivemap-tmp")
    except OSError as exc:
        if exc.errno == errno.ENAMETOOLONG:
            return [_error(target, exc.strerror or str(exc))]
        return [_error(folder, f"cannot write {target.name} here: {exc.strerror or exc}")]
    try:
        os.fchmod(fd, _file_mode(target))
        with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as handle:
            handle.write(text)
        os.replace(tmp, target)
    except OSError as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if exc.errno == errno.ENAMETOOLONG:
            return [_error(target, exc.strerror or str(exc))]
        return [_error(target, f"cannot write: {exc.strerror or exc}")]
    return []

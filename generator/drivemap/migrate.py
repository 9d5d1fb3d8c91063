"""``drivemap migrate [PATH...] [--write]``: rewrite maps of an older format to the current one.

Each map of an older format (``drivemap: 1``) is rewritten in place by editing lines
(:func:`drivemap.frontend.formats.migrate_text`): the format number is replaced and each key the new
format requires is inserted next to its sibling, so comments, order and layout stay as written.
Without ``--write`` the unified diff is printed and nothing is written; with ``--write`` the diff is
printed and the file replaced (atomically). A rewritten map must validate, or nothing is written.

The file is read as it is on disk (regular files only, bounded: :func:`~drivemap.frontend.load.read_map_text`)
and its line endings are kept (CRLF stays CRLF; an inserted line takes its sibling's ending), so the
diff shows exactly the bytes written. ``--write`` never replaces a symbolic link or a file with other
hard links (replacing it would leave the other names on the old format): such a map is an error
naming the link, as ``build`` does.
"""

from __future__ import annotations

import difflib
import os
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

from drivemap.compiler import compile_text, display_path
from drivemap.diagnostics import CompileError, Diagnostic, Location
from drivemap.frontend import formats
from drivemap.frontend.load import load_text, read_map_text


def migrate_file(path: Path) -> tuple[str, str]:
    """(old text, new text) of one map; the new text is checked by compiling it."""
    shown = display_path(path)
    text = read_map_text(shown)  # line endings as on disk
    doc = load_text(text, shown)
    new = formats.migrate_text(text, doc)
    if new != text:
        _check(path, new)
    return text, new


def _check(path: Path, text: str) -> None:
    """Compile the migrated text as the map at ``path`` (nothing is written)."""
    try:
        compile_text(text, path)
    except CompileError as exc:
        raise CompileError([Diagnostic(d.location, f"after migration: {d.message}", d.severity, d.related)
                            for d in exc.diagnostics]) from None


def link_problem(path: Path) -> str | None:
    """Why ``path`` is not replaced (a symbolic link, or a file with other hard links), or None."""
    if path.is_symlink():
        return (f"is a symbolic link (to {os.readlink(path)}): drivemap never writes through links; migrate the "
                "file it points to")
    links = os.stat(path).st_nlink
    if links > 1:
        return (f"has {links} hard links: replacing it would leave the other names on the old format; migrate "
                "one name after removing the others (or copy it)")
    return None


def write_atomic(path: Path, text: str) -> None:
    handle, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(handle, "w", encoding="utf-8", newline="") as out:
            out.write(text)
        os.chmod(tmp, path.stat().st_mode & 0o777)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def run(files: Sequence[Path], write: bool) -> int:
    errors: list[Diagnostic] = []
    changed = 0
    for path in files:
        try:
            old, new = migrate_file(path)
        except CompileError as exc:
            errors.extend(exc.diagnostics)
            continue
        shown = display_path(path)
        if new == old:
            print(f"{shown}: format {formats.CURRENT} already", file=sys.stderr)
            continue
        if write:
            problem = link_problem(path)
            if problem is not None:
                errors.append(Diagnostic(Location(shown, 1, 1), f"{problem}; nothing written"))
                continue
        changed += 1
        sys.stdout.writelines(difflib.unified_diff(old.splitlines(keepends=True), new.splitlines(keepends=True),
                                                   f"a/{shown}", f"b/{shown}"))
        if write:
            write_atomic(path, new)
            print(f"{shown}: migrated to format {formats.CURRENT}", file=sys.stderr)
    if errors:
        raise CompileError(errors)
    if changed and not write:
        print(f"{changed} map{'s' if changed != 1 else ''} to migrate; run again with --write to apply",
              file=sys.stderr)
    return 0


__all__ = ["migrate_file", "run"]

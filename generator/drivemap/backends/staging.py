"""One build per output folder at a time, and staging files that only their own build removes.

- :func:`locked` takes an exclusive lock on the output folder itself (``flock`` on the folder, so a
  killed build never leaves a stale lock); a second build waits up to :data:`LOCK_WAIT` seconds, then
  stops with an error naming the process that holds it (from ``.drivemap-lock``, written while held).
- A build records the staging files it is about to create in ``.drivemap-staging.json`` before it
  creates any; the next build (holding the lock, so the recorder is dead) removes exactly those files
  and nothing else. No file is ever removed because of its name alone.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import sys
import time
from collections.abc import Iterable, Iterator
from pathlib import Path

from drivemap.diagnostics import CompileError, Diagnostic, Location
from drivemap.frontend.project import display

__all__ = ["JOURNAL", "LOCK", "LOCK_WAIT", "TMP_PREFIX", "link_in", "locked", "record", "sweep"]

TMP_PREFIX = ".drivemap-tmp-"
JOURNAL = ".drivemap-staging.json"
LOCK = ".drivemap-lock"
#: Seconds a build waits for another build of the same folder to finish.
LOCK_WAIT = 60.0


def link_in(root: Path, rel: str) -> Path | None:
    """The first symbolic link on the way from ``root`` to ``root / rel`` (the target included)."""
    path = root
    for part in Path(rel).parts:
        path = path / part
        if path.is_symlink():
            return path
    return None


def _holder(root: Path) -> str:
    try:
        info = (root / LOCK).read_text(encoding="utf-8", errors="replace").strip()[:200]
    except OSError:
        info = ""
    return f" (held by {info})" if info else ""


@contextlib.contextmanager
def locked(roots: Iterable[Path], wait: float | None = None) -> Iterator[None]:
    """Hold the build lock of every folder in ``roots`` (taken in sorted order: no deadlock)."""
    with contextlib.ExitStack() as stack:
        for root in sorted({Path(os.path.abspath(r)) for r in roots}):
            stack.enter_context(_lock_one(root, LOCK_WAIT if wait is None else wait))
        yield


@contextlib.contextmanager
def _lock_one(root: Path, wait: float) -> Iterator[None]:
    created = not root.exists()
    try:
        root.mkdir(parents=True, exist_ok=True)
        fd = os.open(root, os.O_RDONLY | os.O_DIRECTORY)
    except OSError as exc:
        raise CompileError([Diagnostic(Location(display(root), 1, 1), f"cannot use as output folder: "
                                                                      f"{exc.strerror or exc}")]) from None
    try:
        deadline = time.monotonic() + wait
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() >= deadline:
                    raise CompileError([Diagnostic(Location(display(root), 1, 1),
                                                   f"another drivemap build is writing this folder{_holder(root)}; "
                                                   f"waited {wait:g} s: try again when it has finished")]) from None
                time.sleep(0.05)
        info = root / LOCK
        with contextlib.suppress(OSError):
            info.write_text(f"pid {os.getpid()}: {' '.join(sys.argv)[:150]}\n", encoding="utf-8")
        try:
            yield
        finally:
            with contextlib.suppress(OSError):
                info.unlink()
            if created:
                with contextlib.suppress(OSError):
                    root.rmdir()  # nothing was written: leave no empty folder behind
    finally:
        os.close(fd)


def record(root: Path, files: Iterable[str]) -> None:
    """Write down the staging files (relative to ``root``) this build is about to create."""
    data = {"version": 1, "pid": os.getpid(), "files": sorted(files)}
    tmp = root / f"{TMP_PREFIX}journal"
    with open(tmp, "w", encoding="utf-8") as handle:
        json.dump(data, handle)
    os.replace(tmp, root / JOURNAL)


def forget(root: Path) -> None:
    with contextlib.suppress(FileNotFoundError):
        (root / JOURNAL).unlink()


def sweep(root: Path) -> list[str]:
    """Remove the staging files a dead earlier build recorded (call with the lock held); return them."""
    removed: list[str] = []
    for fixed in (f"{TMP_PREFIX}journal", f"{TMP_PREFIX}manifest"):  # drivemap's own fixed names, top level
        path = root / fixed
        if path.is_file() and not path.is_symlink():
            path.unlink()
    try:
        data = json.loads((root / JOURNAL).read_text(encoding="utf-8"))
        files = [str(f) for f in data["files"]]
    except FileNotFoundError:
        return removed
    except (OSError, ValueError, KeyError, TypeError):
        files = []  # an unreadable record removes nothing
    for rel in files:
        parts = Path(rel).parts
        if not parts or Path(rel).is_absolute() or ".." in parts or not parts[-1].startswith(TMP_PREFIX):
            continue
        path = root / rel
        if link_in(root, rel) is None and path.is_file():
            try:
                path.unlink()
                removed.append(rel)
            except OSError as exc:
                if exc.errno != errno.ENOENT:
                    raise
    forget(root)
    return removed

"""The per-user cache of compiled maps and rendered builds: never a source of truth.

An entry is a value drivemap computed from files it can read again (a compiled :class:`Model`, the
files a build renders), stored under a key that is the SHA-256 of everything the value depends
on: the cache format, drivemap's version and a fingerprint of its installed code (each source,
template and schema file's size and modification time, so an edited or reinstalled drivemap never
reads an entry of another), the Python version, and the caller's inputs (a map's bytes, the path
it is shown as, ...). A caller that depends on more files than it can name in advance (the maps a
map ``extends``) stores their hashes in the entry and checks them on load.

**Where.** ``$DRIVEMAP_CACHE_DIR``, else ``$XDG_CACHE_HOME/drivemap``, else ``~/.cache/drivemap``.
``DRIVEMAP_NO_CACHE=1`` (or a verb's ``--no-cache``, :func:`disabled`) turns it off.

**Trust.** Entries are pickles, and a pickle runs code when it is loaded, so the cache is read
only from a folder that is the user's own: owned by the user who runs drivemap and writable by
nobody else (drivemap creates it ``0700``); each entry file must be the user's too. Anyone who can
write there can already run code as that user. A folder that fails the check is not used (nothing
is read from it or written to it). On load, the file's first line (a magic word, the cache format,
drivemap's version, the kind and the key, which is also the file's name) must be exactly what the
caller expects before anything is unpickled; an entry that fails the check, or that cannot be
unpickled, or holds a value of the wrong shape, is ignored, and the caller rebuilds the value and
replaces it.

**Concurrency.** An entry is written to a temporary file in the cache folder and renamed over the
entry (:func:`os.replace`, atomic): a reader sees a whole entry or none. Two runs that build the
same entry write the same value; the last rename wins.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import os
import pickle
import stat
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from drivemap import __version__

__all__ = ["FORMAT", "cache_dir", "code_fingerprint", "disabled", "enabled", "key", "load", "store"]

#: The layout of an entry (bump when the header or the meaning of a stored value changes).
FORMAT = 1
MAGIC = b"drivemap-cache"
#: Entries kept per folder; beyond it, the least recently used half is removed when one is stored.
MAX_ENTRIES = 2000
#: Suffixes of the installed files whose change makes every entry stale.
_CODE_SUFFIXES = (".py", ".json", ".jinja", ".yaml", ".toml")

_OFF: list[bool] = []


def enabled() -> bool:
    """Whether the cache is used (not ``DRIVEMAP_NO_CACHE``, not inside :func:`disabled`)."""
    return not _OFF and os.environ.get("DRIVEMAP_NO_CACHE", "") in ("", "0")


@contextlib.contextmanager
def disabled(off: bool = True) -> Iterator[None]:
    """Within the block, nothing is read from or written to the cache (when ``off``)."""
    if off:
        _OFF.append(True)
    try:
        yield
    finally:
        if off:
            _OFF.pop()


def cache_dir() -> Path:
    """The cache folder (which need not exist yet)."""
    explicit = os.environ.get("DRIVEMAP_CACHE_DIR")
    if explicit:
        return Path(explicit)
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg) if xdg and os.path.isabs(xdg) else Path.home() / ".cache"
    return base / "drivemap"


@functools.lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """drivemap's version, the Python version and the size and mtime of every installed file of
    drivemap that decides what it computes (computed once per process)."""
    root = Path(__file__).resolve().parent
    h = hashlib.sha256(f"{FORMAT} {__version__} {sys.version_info[:2]} {root}".encode())
    for folder, dirs, files in os.walk(root):
        dirs[:] = sorted(d for d in dirs if d != "__pycache__")
        for name in sorted(files):
            if name.endswith(_CODE_SUFFIXES):
                path = os.path.join(folder, name)
                try:
                    st = os.stat(path)
                except OSError:
                    continue
                h.update(f"{os.path.relpath(path, root)}\0{st.st_size}\0{st.st_mtime_ns}\n".encode())
    return h.hexdigest()


def key(*parts: str | bytes) -> str:
    """The key of an entry: the SHA-256 of the code fingerprint and ``parts``."""
    h = hashlib.sha256(code_fingerprint().encode())
    for part in parts:
        data = part.encode("utf-8", "surrogateescape") if isinstance(part, str) else part
        h.update(len(data).to_bytes(8, "big"))
        h.update(data)
    return h.hexdigest()


def _header(kind: str, entry_key: str) -> bytes:
    return b" ".join((MAGIC, str(FORMAT).encode(), __version__.encode(), kind.encode(), entry_key.encode())) + b"\n"


def _path(folder: Path, kind: str, entry_key: str) -> Path:
    return folder / f"{kind}-{__version__}-{entry_key}.pickle"


def _own_folder(folder: Path) -> bool:
    """The folder exists, is a real folder (no link), is the user's and no one else may write to it."""
    try:
        st = os.lstat(folder)
    except OSError:
        return False
    return stat.S_ISDIR(st.st_mode) and st.st_uid == os.getuid() and not st.st_mode & 0o022


def load(kind: str, entry_key: str) -> Any | None:
    """The value stored under ``kind``/``entry_key``, or None (no cache, no entry, or an entry that
    is not exactly one this drivemap wrote: it is ignored)."""
    if not enabled():
        return None
    folder = cache_dir()
    if not _own_folder(folder):
        return None
    path = _path(folder, kind, entry_key)
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
    except OSError:
        return None
    try:
        with os.fdopen(fd, "rb") as handle:
            st = os.fstat(handle.fileno())
            if not stat.S_ISREG(st.st_mode) or st.st_uid != os.getuid():
                return None
            header = _header(kind, entry_key)
            if handle.read(len(header)) != header:
                return None
            return pickle.loads(handle.read())  # noqa: S301 - the user's own folder, header checked (see above)
    except Exception:  # noqa: BLE001 - a corrupt entry is ignored and rebuilt, whatever unpickling raised
        return None


def store(kind: str, entry_key: str, value: Any) -> None:
    """Store ``value`` (best effort: a cache that cannot be written is not an error)."""
    if not enabled():
        return
    folder = cache_dir()
    try:
        folder.mkdir(parents=True, exist_ok=True, mode=0o700)
    except OSError:
        return
    if not _own_folder(folder):
        return
    try:
        data = _header(kind, entry_key) + pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL)
    except Exception:  # noqa: BLE001 - a value that does not pickle is simply not cached
        return
    tmp = None
    try:
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=".tmp-", suffix=".pickle")
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
        os.replace(tmp, _path(folder, kind, entry_key))
        tmp = None
    except OSError:
        pass
    finally:
        if tmp is not None:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
    _prune(folder)


def _prune(folder: Path) -> None:
    """Keep at most :data:`MAX_ENTRIES` entries: drop the least recently used half beyond it."""
    try:
        entries = [e for e in os.scandir(folder) if e.name.endswith(".pickle") and not e.name.startswith(".")]
        if len(entries) <= MAX_ENTRIES:
            return
        entries.sort(key=lambda e: e.stat().st_atime)
        for entry in entries[: len(entries) - MAX_ENTRIES // 2]:
            with contextlib.suppress(OSError):
                os.unlink(entry.path)
    except OSError:
        return

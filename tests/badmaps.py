"""The golden corpus of broken maps, kept as a few base maps and one small patch per case.

``tests/bad_maps/<case>.patch`` is a unified diff against a base in ``tests/bad_maps/_bases/`` (its
``---`` line names which; ``{case}`` in a base stands for the case's name); a case that shares little
with any base (a YAML bomb, an empty file, a map that extends another) stays a whole
``tests/bad_maps/<case>.yaml``. :func:`materialize` writes every case as the file ``drivemap validate``
reads, at the same relative path (``tests/bad_maps/<case>.yaml``, beside a copy of ``maps/`` for the
cases that extend a shipped map), so each case's messages are byte for byte its ``<case>.expected``.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

HERE = Path(__file__).resolve().parent
CORPUS = HERE / "bad_maps"
ROOT = HERE.parent

_HUNK = re.compile(r"@@ -(\d+)(?:,(\d+))? \+(\d+)(?:,(\d+))? @@")


class PatchError(ValueError):
    """A patch that does not apply to its base (the base changed, or the patch was edited by hand)."""


def case_names() -> list[str]:
    return sorted({p.stem for p in CORPUS.glob("*.yaml")} | {p.stem for p in CORPUS.glob("*.patch")})


def apply(base: str, patch: str, name: str) -> str:
    """``patch`` (a unified diff) applied to ``base``; every context and removed line must match."""
    old = base.replace("{case}", name).splitlines(keepends=True)
    out: list[str] = []
    at = 0  # lines of ``old`` consumed
    lines = patch.splitlines(keepends=True)
    i = next((k for k, line in enumerate(lines) if line.startswith("@@")), len(lines))
    while i < len(lines):
        m = _HUNK.match(lines[i])
        if m is None:
            raise PatchError(f"{name}.patch: expected a hunk header, got {lines[i]!r}")
        start = int(m.group(1)) - (0 if m.group(2) == "0" else 1)
        out.extend(old[at:start])
        at = start
        i += 1
        while i < len(lines) and not lines[i].startswith("@@"):
            tag, text = lines[i][:1], lines[i][1:]
            if tag in (" ", "-"):
                if at >= len(old) or old[at] != text:
                    raise PatchError(f"{name}.patch: line {at + 1} of the base is not {text!r}")
                at += 1
            if tag in (" ", "+"):
                out.append(text)
            i += 1
    out.extend(old[at:])
    return "".join(out)


def case_bytes(name: str) -> bytes:
    """The map file of case ``name``, as ``drivemap validate`` reads it."""
    whole = CORPUS / f"{name}.yaml"
    if whole.exists():
        return whole.read_bytes()
    patch = (CORPUS / f"{name}.patch").read_text(encoding="utf-8")
    first = patch.splitlines()[0]
    if not first.startswith("--- "):
        raise PatchError(f"{name}.patch: the first line names the base ('--- _bases/NAME.yaml')")
    base = (CORPUS / first[4:].strip()).read_text(encoding="utf-8")
    return apply(base, patch, name).encode("utf-8")


def case_text(name: str) -> str:
    return case_bytes(name).decode("utf-8")


def materialize(dest: Path) -> Path:
    """Every case written under ``dest`` as ``tests/bad_maps/<case>.yaml`` (and a copy of ``maps/``
    beside them, which the cases that extend a shipped map name); returns ``dest``."""
    folder = dest / "tests" / "bad_maps"
    folder.mkdir(parents=True, exist_ok=True)
    for name in case_names():
        (folder / f"{name}.yaml").write_bytes(case_bytes(name))
    maps = dest / "maps"
    maps.mkdir(exist_ok=True)
    for path in (ROOT / "maps").glob("*.yaml"):
        shutil.copyfile(path, maps / path.name)
    return dest

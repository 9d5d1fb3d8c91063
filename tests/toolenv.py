"""Third-party tools (ESPHome, Home Assistant, pymodbus.simulator) in their own virtualenvs, cached between runs.

Each tool gets a virtualenv of its own under ``~/.cache/drivemap-tools`` (``DRIVEMAP_TOOLS_CACHE``
overrides it), outside the repository, so its pins never meet drivemap's and a rerun reuses it. A
virtualenv counts as ready only once its install finished (a marker file written last); a broken
or half-made one is rebuilt. When pip cannot install the package, the test is skipped with pip's
own words in the reason (pytest prints it in its summary: ``-ra``), never silently.

    python tests/toolenv.py esphome      # prepare one ahead of a test run (prints its bin folder)
"""

from __future__ import annotations

import fcntl
import os
import re
import shutil
import subprocess
import sys
import venv
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

#: The pins the `tools` tests validate against. ESPHome: the newest release installable on Python
#: 3.11. Home Assistant: 2024.3 is the last release line for Python 3.11 (the current one needs
#: 3.13), so the exporter's `--ha-version 2024.3` output is what the real check reads.
TOOLS: dict[str, str] = {
    "esphome": "esphome==2026.6.5",
    "homeassistant": "homeassistant==2024.3.3",
    # pymodbus's own simulator CLI (pymodbus.simulator needs the aiohttp extra; same pymodbus as ours)
    "pymodbus-simulator": "pymodbus[simulator]==3.16.1",
}

INSTALL_TIMEOUT_S = 1800


def cache_root() -> Path:
    return Path(os.environ.get("DRIVEMAP_TOOLS_CACHE") or Path.home() / ".cache" / "drivemap-tools")


@dataclass(frozen=True)
class Tool:
    name: str
    requirement: str
    folder: Path

    @property
    def bin(self) -> Path:
        return self.folder / "bin"

    def exe(self, name: str) -> Path:
        return self.bin / name


class ToolUnavailable(Exception):
    """The tool's package could not be installed here (the message says why, in pip's words)."""


@contextmanager
def _locked(path: Path) -> Iterator[None]:
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def _folder(requirement: str) -> Path:
    tag = re.sub(r"[^A-Za-z0-9.]+", "-", requirement).strip("-")
    return cache_root() / f"{tag}-py{sys.version_info.major}.{sys.version_info.minor}"


def ensure(name: str) -> Tool:
    """The tool's virtualenv, created and installed on first use; :class:`ToolUnavailable` if pip fails."""
    requirement = TOOLS[name]
    folder = _folder(requirement)
    tool = Tool(name, requirement, folder)
    marker = folder / ".drivemap-ready"
    if marker.is_file():
        return tool
    with _locked(folder.with_name(folder.name + ".lock")):
        if marker.is_file():
            return tool
        shutil.rmtree(folder, ignore_errors=True)
        venv.EnvBuilder(with_pip=True, clear=True).create(folder)
        python = folder / "bin" / "python"
        command = [str(python), "-m", "pip", "install", "--quiet", "--disable-pip-version-check", requirement]
        try:
            done = subprocess.run(command, capture_output=True, text=True, timeout=INSTALL_TIMEOUT_S, check=False)
        except subprocess.TimeoutExpired:
            raise ToolUnavailable(f"pip install {requirement} did not finish in {INSTALL_TIMEOUT_S} s") from None
        if done.returncode != 0:
            tail = "\n".join((done.stderr or done.stdout).strip().splitlines()[-8:])
            raise ToolUnavailable(f"pip install {requirement} failed (exit {done.returncode}):\n{tail}")
        marker.write_text(requirement + "\n", encoding="utf-8")
    return tool


def require(name: str) -> Tool:
    """:func:`ensure` for tests: a tool that cannot be installed FAILS the test (a check not run is no pass)."""
    import pytest

    try:
        return ensure(name)
    except ToolUnavailable as exc:
        message = f"TOOL NOT INSTALLED, CHECK NOT RUN: {name} ({TOOLS[name]}): {exc}"
        print(f"\n*** {message}", file=sys.stderr)
        pytest.fail(message)


if __name__ == "__main__":
    for arg in sys.argv[1:] or list(TOOLS):
        print(ensure(arg).bin)

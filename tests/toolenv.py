"""Third-party tools (ESPHome, Home Assistant, pymodbus.simulator; node-opcua from npm), cached between runs.

Each Python tool gets a virtualenv of its own under ``~/.cache/drivemap-tools`` (``DRIVEMAP_TOOLS_CACHE``
overrides it), outside the repository, so its pins never meet drivemap's and a rerun reuses it; a tool
may need several requirements (Home Assistant that runs needs what it would pip-install at start).
An npm tool gets a folder there with its package.json and node_modules. A tool counts as ready only
once its install finished (a marker file written last); a broken or half-made one is rebuilt. When
pip or npm cannot install it, the test FAILS with the installer's own words (a check not run is no
pass); installs are bounded by ``INSTALL_TIMEOUT_S``.

    python tests/toolenv.py esphome      # prepare one ahead of a test run (prints its folder)
"""

from __future__ import annotations

import fcntl
import hashlib
import json
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
#: A tool is one requirement or several (the first names the tool; the folder name carries a hash
#: of the others, so a changed list gets a fresh virtualenv).
TOOLS: dict[str, str | tuple[str, ...]] = {
    # the newest ESPHome release (needs Python 3.12+: TOOL_PYTHON) and the oldest one the exporter supports
    # (--esphome-version; drivemap.backends.exporters.esphome NEWEST / OLDEST)
    "esphome": "esphome==2026.10.0",
    "esphome-oldest": "esphome==2026.6.5",
    # check_config (tests/backends/exporters/test_exporters_tools.py) and a Home Assistant that *runs* (`hass -c CFG
    # --skip-pip`, tests/gateway/test_ha_live.py): with what HA would otherwise pip-install at start for its
    # core, recorder, frontend, http, modbus and mqtt (a frontend that fails to set up sends HA into
    # recovery mode, which loads no integration)
    "homeassistant": (
        "homeassistant==2024.3.3", "pymodbus==3.6.6", "SQLAlchemy==2.0.27", "fnv-hash-fast==0.5.0",
        "psutil-home-assistant==0.0.1", "paho-mqtt==1.6.1", "home-assistant-frontend==20240307.0",
        "Pillow==10.2.0", "janus==1.0.0", "securetar==2024.2.1", "josepy<2",
        "aiohttp-fast-url-dispatcher==0.3.0", "aiohttp-zlib-ng==0.3.1", "aiohttp_cors==0.7.0",
    ),
    # pymodbus's own simulator CLI (pymodbus.simulator needs the aiohttp extra; same pymodbus as ours)
    "pymodbus-simulator": "pymodbus[simulator]==3.16.1",
}

#: tools that need another Python than the one running the tests: the interpreter's X.Y. It is looked up on
#: PATH (pythonX.Y) and under pyenv's versions ($PYENV_ROOT or ~/.pyenv); where none is found the test FAILS
#: saying which interpreter to install (.ci/run checks for it before the tools tier).
TOOL_PYTHON: dict[str, str] = {"esphome": "3.12"}

#: npm packages, each in a folder of its own (package.json + node_modules) under the same cache.
NPM_TOOLS: dict[str, tuple[str, ...]] = {
    # an OPC UA client that is not the asyncua the gateway's server is built on
    "node-opcua": ("node-opcua@2.186.4",),
}

INSTALL_TIMEOUT_S = 1800


def cache_root() -> Path:
    return Path(os.environ.get("DRIVEMAP_TOOLS_CACHE") or Path.home() / ".cache" / "drivemap-tools")


@dataclass(frozen=True)
class Tool:
    name: str
    requirement: str | tuple[str, ...]
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


def _requirements(requirement: str | tuple[str, ...]) -> list[str]:
    return [requirement] if isinstance(requirement, str) else list(requirement)


def interpreter(version: str) -> Path:
    """A Python X.Y interpreter that runs: the newest pyenv X.Y.*, else ``pythonX.Y`` on PATH (a pyenv shim
    of a version not selected does not run); :class:`ToolUnavailable` if none."""
    root = Path(os.environ.get("PYENV_ROOT") or Path.home() / ".pyenv")
    candidates = sorted((root / "versions").glob(f"{version}.*/bin/python{version}"),
                        key=lambda p: [int(x) for x in re.findall(r"\d+", p.parent.parent.name)])
    found = shutil.which(f"python{version}")
    for candidate in [*reversed(candidates), *([Path(found)] if found else [])]:
        ran = subprocess.run([str(candidate), "-c", "import sys, venv; print(sys.version_info[:2])"],
                             capture_output=True, text=True, check=False)
        if ran.returncode == 0 and ran.stdout.strip() == str(tuple(int(x) for x in version.split("."))):
            return candidate
    raise ToolUnavailable(f"Python {version} is needed and was not found (neither python{version} on PATH nor "
                          f"{root}/versions/{version}.*): install it, e.g. `pyenv install {version}`")


def _python_of(name: str) -> tuple[str, Path | None]:
    """The X.Y a tool's virtualenv runs and its interpreter (None: the one running the tests)."""
    version = TOOL_PYTHON.get(name)
    if version is None:
        return f"{sys.version_info.major}.{sys.version_info.minor}", None
    return version, interpreter(version)


def _folder(requirement: str | tuple[str, ...], python: str | None = None) -> Path:
    wanted = _requirements(requirement)
    tag = re.sub(r"[^A-Za-z0-9.]+", "-", wanted[0]).strip("-")
    if len(wanted) > 1:
        tag += "-" + hashlib.sha256("\n".join(wanted).encode()).hexdigest()[:8]
    return cache_root() / f"{tag}-py{python or f'{sys.version_info.major}.{sys.version_info.minor}'}"


def ensure(name: str) -> Tool:
    """The tool's virtualenv, created and installed on first use; :class:`ToolUnavailable` if pip fails."""
    requirement = TOOLS[name]
    version, base = _python_of(name)
    folder = _folder(requirement, version)
    tool = Tool(name, requirement, folder)
    marker = folder / ".drivemap-ready"
    if marker.is_file():
        return tool
    with _locked(folder.with_name(folder.name + ".lock")):
        if marker.is_file():
            return tool
        shutil.rmtree(folder, ignore_errors=True)
        if base is None:
            venv.EnvBuilder(with_pip=True, clear=True).create(folder)
        else:
            made = subprocess.run([str(base), "-m", "venv", "--clear", str(folder)], capture_output=True, text=True,
                                  check=False)
            if made.returncode != 0:
                raise ToolUnavailable(f"{base} -m venv {folder} failed: {(made.stderr or made.stdout).strip()[-500:]}")
        python = folder / "bin" / "python"
        wanted = _requirements(requirement)
        command = [str(python), "-m", "pip", "install", "--quiet", "--disable-pip-version-check", *wanted]
        try:
            done = subprocess.run(command, capture_output=True, text=True, timeout=INSTALL_TIMEOUT_S, check=False)
        except subprocess.TimeoutExpired:
            raise ToolUnavailable(f"pip install {' '.join(wanted)} did not finish in {INSTALL_TIMEOUT_S} s") from None
        if done.returncode != 0:
            tail = "\n".join((done.stderr or done.stdout).strip().splitlines()[-8:])
            raise ToolUnavailable(f"pip install {' '.join(wanted)} failed (exit {done.returncode}):\n{tail}")
        marker.write_text("\n".join(wanted) + "\n", encoding="utf-8")
    return tool


@dataclass(frozen=True)
class NodeTool:
    name: str
    packages: tuple[str, ...]
    folder: Path  # package.json and node_modules; run scripts with cwd=folder so require() finds them

    @property
    def node(self) -> str:
        return shutil.which("node") or "node"


def ensure_npm(name: str) -> NodeTool:
    """An npm package set in its own folder, installed on first use; :class:`ToolUnavailable` if npm fails."""
    packages = NPM_TOOLS[name]
    tag = re.sub(r"[^A-Za-z0-9.]+", "-", "-".join(packages)).strip("-")
    folder = cache_root() / f"npm-{tag}"
    tool = NodeTool(name, packages, folder)
    marker = folder / ".drivemap-ready"
    if marker.is_file():
        return tool
    node, npm = shutil.which("node"), shutil.which("npm")
    if node is None or npm is None:
        raise ToolUnavailable(f"node and npm must be on PATH to install {' '.join(packages)} (node={node}, npm={npm})")
    with _locked(folder.with_name(folder.name + ".lock")):
        if marker.is_file():
            return tool
        shutil.rmtree(folder, ignore_errors=True)
        folder.mkdir(parents=True)
        manifest = {"name": f"drivemap-tools-{name}", "version": "0.0.0", "private": True}
        (folder / "package.json").write_text(json.dumps(manifest, indent=2) + "\n", encoding="utf-8")
        command = [npm, "install", "--no-audit", "--no-fund", "--loglevel=error", "--save-exact", *packages]
        try:
            done = subprocess.run(command, cwd=folder, capture_output=True, text=True, timeout=INSTALL_TIMEOUT_S,
                                  check=False)
        except subprocess.TimeoutExpired:
            raise ToolUnavailable(f"npm install {' '.join(packages)} did not finish in {INSTALL_TIMEOUT_S} s") from None
        if done.returncode != 0:
            tail = "\n".join((done.stderr or done.stdout).strip().splitlines()[-8:])
            raise ToolUnavailable(f"npm install {' '.join(packages)} failed (exit {done.returncode}):\n{tail}")
        marker.write_text("\n".join(packages) + "\n", encoding="utf-8")
    return tool


def require_npm(name: str) -> NodeTool:
    """:func:`ensure_npm` for tests: an npm tool that cannot be installed FAILS the test, with npm's words."""
    import pytest

    try:
        return ensure_npm(name)
    except ToolUnavailable as exc:
        message = f"TOOL NOT INSTALLED, CHECK NOT RUN: {name} ({' '.join(NPM_TOOLS[name])}): {exc}"
        print(f"\n*** {message}", file=sys.stderr)
        pytest.fail(message)


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
    for arg in sys.argv[1:] or [*TOOLS, *NPM_TOOLS]:
        print(ensure_npm(arg).folder if arg in NPM_TOOLS else ensure(arg).bin)

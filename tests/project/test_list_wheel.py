"""The catalogue from an installed wheel: a wheel built with catalogue maps below ``maps/catalogue/``
ships them as package data, and in an empty folder `drivemap list` shows them and a model id finds one
(slow: builds a wheel and a virtualenv, like tests/project/test_wheel.py)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import venv
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
FIXTURES = ROOT / "tests" / "fixtures" / "catalogue_list"

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A wheel of this checkout with the fixture catalogue added under maps/catalogue/ (a copy: the
    checkout is not touched)."""
    src = tmp_path_factory.mktemp("src") / "drivemap"
    skip = shutil.ignore_patterns("__pycache__", "*.egg-info", ".drivemap-manifest.json")
    src.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, src / name)
    for name in ("generator", "generated", "maps", "schemas"):
        shutil.copytree(ROOT / name, src / name, symlinks=True, ignore=skip)
    (src / "docs" / "examples").mkdir(parents=True)
    shutil.copy(ROOT / "docs" / "examples" / "plant.yaml", src / "docs" / "examples")
    shutil.copytree(FIXTURES, src / "maps" / "catalogue", dirs_exist_ok=True)
    dist = tmp_path_factory.mktemp("dist")
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(dist), str(src)],
                   check=True, capture_output=True, text=True, timeout=600)
    (found,) = dist.glob("drivemap-*.whl")
    return found


@pytest.fixture(scope="module")
def bindir(wheel: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    where = tmp_path_factory.mktemp("venv") / "v"
    venv.EnvBuilder(with_pip=True).create(where)
    subprocess.run([str(where / "bin" / "python"), "-m", "pip", "install", "-q", str(wheel)], check=True,
                   capture_output=True, text=True, timeout=900)
    return where / "bin"


def drivemap(bindir: Path, cwd: Path, *argv: str) -> subprocess.CompletedProcess[str]:
    clean = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    clean["PATH"] = f"{bindir}{os.pathsep}{clean.get('PATH', '')}"
    return subprocess.run([str(bindir / "drivemap"), *argv], cwd=cwd, env=clean, capture_output=True, text=True,
                          timeout=300)


def test_the_wheel_holds_the_catalogue(wheel: Path) -> None:
    names = set(zipfile.ZipFile(wheel).namelist())
    for path in FIXTURES.rglob("*.yaml"):
        assert f"drivemap/data/maps/catalogue/{path.relative_to(FIXTURES).as_posix()}" in names
    assert "drivemap/data/maps/sdm630.yaml" in names


def test_list_and_lookup_by_id_from_the_installed_wheel(bindir: Path, tmp_path: Path) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    proc = drivemap(bindir, empty, "list", "--kind", "meter")
    assert proc.returncode == 0, proc.stderr
    assert "acme_em100" in proc.stdout and "acme_em200" in proc.stdout and "zeta_inv5k" not in proc.stdout
    assert "catalogue/evcc" in proc.stdout and "imported" in proc.stdout
    proc = drivemap(bindir, empty, "list")
    assert "sdm630" in proc.stdout and "zeta_inv5k" in proc.stdout and "catalogue/solarman" in proc.stdout
    proc = drivemap(bindir, empty, "export", "zeta_inv5k", "--format", "json")
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["model"] == "zeta_inv5k"
    assert "using the catalogue map" in proc.stderr and "Traceback" not in proc.stderr
    assert sorted(p.name for p in empty.iterdir()) == []  # nothing written where the user stands

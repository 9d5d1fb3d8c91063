"""A third-party exporter from another distribution is found with no change to drivemap.

The plugin is a real distribution (pyproject + module) built and installed by pip into a folder of
its own; ``python -m drivemap`` then runs with that folder on PYTHONPATH.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]

PYPROJECT = """\
[build-system]
requires = ["setuptools>=61"]
build-backend = "setuptools.build_meta"

[project]
name = "drivemap-count-exporter"
version = "0.1"

[project.entry-points."drivemap.exporters"]
count = "drivemap_count:CountExporter"
"""

MODULE = '''\
"""Counts registers (a plugin exporter living in its own distribution)."""
from drivemap.backends.exporters import Exporter


class CountExporter(Exporter):
    name = "count"
    help = "how many registers a map has"
    suffix = ".txt"

    def add_arguments(self, parser):
        parser.add_argument("--label", default="registers")

    def render(self, model, options):
        return {f"{model.name}.txt": f"{model.name}: {len(model.registers)} {options.get('label')}\\n"}
'''


@pytest.fixture(scope="module")
def plugin_site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    source = tmp_path_factory.mktemp("plugin-src")
    (source / "pyproject.toml").write_text(PYPROJECT, encoding="utf-8")
    (source / "drivemap_count.py").write_text(MODULE, encoding="utf-8")
    site = tmp_path_factory.mktemp("plugin-site")
    done = subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps",
                           "--target", str(site), str(source)], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert any(p.name.startswith("drivemap_count_exporter-") and p.suffix == ".dist-info" for p in site.iterdir())
    return site


def _drivemap(site: Path, *argv: str) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(site), str(ROOT / "generator"), str(ROOT / "generated")]))
    return subprocess.run([sys.executable, "-m", "drivemap", *argv], capture_output=True, text=True, cwd=ROOT,
                          env=env, timeout=120)


def test_installed_plugin_is_listed_and_runs(plugin_site: Path) -> None:
    listed = _drivemap(plugin_site, "export", "--list")
    assert listed.returncode == 0, listed.stderr
    assert any(line.split()[0] == "count" and "how many registers" in line for line in listed.stdout.splitlines())
    ran = _drivemap(plugin_site, "export", "ev", "--format", "count", "--label", "regs")
    assert ran.returncode == 0, ran.stderr
    assert ran.stdout.startswith("ev: ") and ran.stdout.rstrip().endswith(" regs")


def test_without_the_plugin_it_is_unknown(tmp_path: Path) -> None:
    missing = _drivemap(tmp_path, "export", "ev", "--format", "count")
    assert missing.returncode == 1
    assert textwrap.dedent("unknown format 'count'") in missing.stderr


def test_multi_device_is_a_declared_protocol_checked_when_the_plugin_loads(monkeypatch: pytest.MonkeyPatch) -> None:
    import sys
    import types

    from drivemap.backends.exporters import _load
    from drivemap.backends.exporters.base import Exporter, MultiDevice
    from drivemap.backends.exporters.homeassistant import HomeAssistantExporter

    class Claims(Exporter):
        name = "claims"
        multi_device = True

    class Line(Claims):
        def render_line(self, devices: object, options: object) -> dict[str, str]:
            return {}

    module = types.ModuleType("drivemap_test_plugins")
    module.Claims, module.Line = Claims, Line  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "drivemap_test_plugins", module)
    with pytest.raises(TypeError, match="declares multi_device but has no render_line"):
        _load("drivemap_test_plugins:Claims")
    assert _load("drivemap_test_plugins:Line") is Line
    assert HomeAssistantExporter.multi_device and isinstance(HomeAssistantExporter(), MultiDevice)

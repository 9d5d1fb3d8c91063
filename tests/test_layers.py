"""The layers hold: import-linter's contracts, validation that renders nothing, and the old import paths."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def test_import_linter_contracts_hold() -> None:
    exe = shutil.which("lint-imports") or str(Path(sys.executable).with_name("lint-imports"))
    proc = subprocess.run([exe], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "BROKEN" not in proc.stdout and "KEPT" in proc.stdout


def test_validate_renders_nothing() -> None:
    """``drivemap validate`` runs the exporters' checks without Jinja, templates, views or in-memory code."""
    script = (
        "import json, sys\n"
        "from drivemap.cli import main\n"
        "code = main(['validate', 'maps/ev.yaml', 'maps/sdm630.yaml'])\n"
        "print(json.dumps([code, sorted(sys.modules)]))\n"
    )
    proc = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True, text=True, timeout=120)
    code, modules = json.loads(proc.stdout.splitlines()[-1])
    assert code == 0, proc.stderr
    rendering = [m for m in modules if m.startswith(("jinja2", "drivemap.backends.render"))
                 or (m.startswith("drivemap.backends.views.") and m != "drivemap.backends.views.format")]
    assert rendering == []
    assert "drivemap.backends.python.namecheck" in modules  # the python exporter's checks did run


def test_a_name_clash_is_still_refused_by_validate(tmp_path: Path) -> None:
    """The generated-name checks moved to the python exporter's hook; validate still runs them."""
    text = (ROOT / "maps" / "v2.yaml").read_text(encoding="utf-8")
    first = text.index("  - name: ", text.index("\nregisters:"))
    end = text.index("\n", first)
    clashing = text[:first] + "  - name: read_all" + text[end:]
    bad = tmp_path / "v2.yaml"
    bad.write_text(clashing, encoding="utf-8")
    proc = subprocess.run([sys.executable, "-m", "drivemap.cli", "validate", str(bad)], cwd=tmp_path,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1
    assert "register name 'read_all' clashes with a client attribute" in proc.stderr
    assert "Traceback" not in proc.stderr


@pytest.mark.parametrize(("old", "new", "name"), [
    ("drivemap.runtime.client", "drivemap.runtime.client.sync_client", "ClientBase"),
    ("drivemap.runtime.bus", "drivemap.runtime.client.bus", "Bus"),
    ("drivemap.runtime.codec", "drivemap.runtime.client.codec", "IntCodec"),
    ("drivemap.runtime.records", "drivemap.runtime.client.records", "record"),
    ("drivemap.runtime.simulator", "drivemap.runtime.sim.simulator", "Simulator"),
    ("drivemap.runtime.simcli", "drivemap.runtime.sim.cli", "main"),
    ("drivemap.behaviours", "drivemap.runtime.sim.behaviours", "register"),
    ("drivemap.model", "drivemap.model.nodes", "Model"),
])
def test_old_public_import_paths_re_export_the_same_objects(old: str, new: str, name: str) -> None:
    import importlib

    assert getattr(importlib.import_module(old), name) is getattr(importlib.import_module(new), name)


def test_runtime_errors_and_seed_clients_keep_their_paths() -> None:
    from drivemap.runtime.errors import DeviceException
    from drivemap_models.ev import Client, MotorState

    assert issubclass(DeviceException, Exception)
    assert Client.__name__ == "Client" and MotorState.__name__ == "MotorState"

"""The layers hold: import-linter's contracts, validation that renders nothing, and the old import paths."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from drivemap._compat import MOVED_MODULES

ROOT = Path(__file__).resolve().parents[2]


def test_import_linter_contracts_hold() -> None:
    exe = shutil.which("lint-imports") or str(Path(sys.executable).with_name("lint-imports"))
    proc = subprocess.run([exe], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "BROKEN" not in proc.stdout and "KEPT" in proc.stdout


def _modules_after(args: list[str]) -> tuple[int, list[str]]:
    script = (
        "import json, sys\n"
        "from drivemap.cli import main\n"
        f"code = main({args!r})\n"
        "print(json.dumps([code, sorted(sys.modules)]))\n"
    )
    # the compile cache off: every map is compiled (a cached model would import even less)
    proc = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True, text=True, timeout=120,
                          env=dict(os.environ, DRIVEMAP_NO_CACHE="1"))
    code, modules = json.loads(proc.stdout.splitlines()[-1])
    return code, modules


def test_validate_imports_nothing_from_backends_or_templates() -> None:
    """``drivemap validate`` is the front end and the model: no back end, no Jinja, no template."""
    code, modules = _modules_after(["validate", "maps/ev.yaml", "maps/sdm630.yaml", "maps/fronius_symo_hybrid.yaml"])
    assert code == 0
    assert [m for m in modules if m.startswith(("drivemap.backends", "jinja2", "drivemap.build"))] == []
    assert "drivemap.model.build" in modules and "drivemap.frontend.checks" in modules  # it did validate


def test_validate_with_exporters_renders_nothing() -> None:
    """``--exporter`` runs the exporters' checks: data and name rules, no Jinja, no views, no rendering."""
    code, modules = _modules_after(["validate", "--exporter", "python", "--exporter", "docs", "maps/ev.yaml"])
    assert code == 0
    rendering = [m for m in modules if m.startswith(("jinja2", "drivemap.backends.render"))
                 or (m.startswith("drivemap.backends.views.") and m != "drivemap.backends.views.format")]
    assert rendering == []
    assert "drivemap.vocab.namecheck" in modules  # the python exporter's checks did run


def test_a_name_clash_is_refused_where_the_python_exporter_runs(tmp_path: Path) -> None:
    """The map language allows ``read_all``; the generated client cannot hold it: ``build`` and
    ``validate --exporter python`` refuse it (located), plain ``validate`` accepts it, nothing is written."""
    text = (ROOT / "maps" / "v2.yaml").read_text(encoding="utf-8")
    first = text.index("  - name: ", text.index("\nregisters:"))
    name = text[first + len("  - name: "):text.index("\n", first)]
    bad = tmp_path / "v2.yaml"
    bad.write_text(re.sub(rf"\b{name}\b", "read_all", text), encoding="utf-8")
    line = text[:first].count("\n") + 1

    def run(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run([sys.executable, "-m", "drivemap.cli", *args], cwd=tmp_path,
                              capture_output=True, text=True, timeout=120)

    assert run("validate", "v2.yaml").returncode == 0
    for args in (("validate", "--exporter", "python", "v2.yaml"), ("build", "v2.yaml"),
                 ("validate", "--exporter", "all", "v2.yaml")):
        proc = run(*args)
        assert proc.returncode == 1, args
        assert proc.stderr.startswith(f"v2.yaml:{line}:"), proc.stderr
        assert "register name 'read_all' clashes with a client attribute" in proc.stderr
        assert "Traceback" not in proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["v2.yaml"]
    proc = run("validate", "--exporter", "nosuch", "v2.yaml")
    assert proc.returncode == 1 and "unknown exporter 'nosuch'" in proc.stderr and "Traceback" not in proc.stderr


@pytest.mark.parametrize(("path", "inner", "name"), [
    ("drivemap.runtime.client", "drivemap.runtime.client.api.sync_client", "ClientBase"),
    ("drivemap.behaviours", "drivemap.runtime.sim.behaviours", "register"),
    ("drivemap.model", "drivemap.model.nodes", "Model"),
])
def test_public_import_paths_re_export_the_same_objects(path: str, inner: str, name: str) -> None:
    import importlib

    assert getattr(importlib.import_module(path), name) is getattr(importlib.import_module(inner), name)


@pytest.mark.parametrize("old", sorted(MOVED_MODULES))
def test_old_import_paths_answer_from_compat_with_a_warning(old: str) -> None:
    """Each moved module's old path gives the new module's very objects, warns once naming the new path
    and the release that removes the old one, and has no module file of its own any more."""
    import importlib

    from drivemap._compat import REMOVAL

    new = importlib.import_module(MOVED_MODULES[old])
    sys.modules.pop(old, None)
    with pytest.warns(DeprecationWarning, match=rf"{re.escape(old)} is now {re.escape(new.__name__)}; "
                                                rf"the old path goes in drivemap {REMOVAL}"):
        module = importlib.import_module(old)
    names = list(getattr(new, "__all__", ()))
    assert names and all(getattr(module, n) is getattr(new, n) for n in names)
    assert not (ROOT / "generator" / (old.replace(".", "/") + ".py")).exists()


def test_an_unknown_old_name_is_an_attribute_error() -> None:
    import importlib
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        module = importlib.import_module("drivemap.runtime.codec")
    with pytest.raises(AttributeError):
        module.NoSuchCodec  # noqa: B018


def test_runtime_errors_and_seed_clients_keep_their_paths() -> None:
    from drivemap.runtime.errors import DeviceException
    from drivemap_models.ev import Client, MotorState

    assert issubclass(DeviceException, Exception)
    assert Client.__name__ == "Client" and MotorState.__name__ == "MotorState"


def test_the_complexity_gate_holds() -> None:
    """No hand-written function past ruff's C901 bound (pyproject's ``max-complexity``): the gate that replaced
    the line caps (a module may grow long when it is one idea; a function may not grow tangled)."""
    proc = subprocess.run([sys.executable, "-m", "ruff", "check", "--no-cache", "--select", "C90",
                           "generator", "bench", "tests"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_no_import_circle_anywhere() -> None:
    """import-linter's acyclic_siblings contract covers every folder of the package (pyproject.toml)."""
    import tomllib

    contracts = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["importlinter"]["contracts"]
    assert {"type": "acyclic_siblings", "ancestors": ["drivemap"]}.items() <= next(
        c for c in contracts if c["type"] == "acyclic_siblings").items()


def test_a_client_package_generated_before_the_runtime_split_still_runs(tmp_path: Path) -> None:
    """A package generated by the release before the client runtime moved into values / transport /
    protocol / api imports the old module paths; it still imports (warning once per old path), plans
    as the new one does and has the same namespace."""
    import importlib
    import warnings

    old_of = {new: old for old, new in MOVED_MODULES.items() if old.startswith("drivemap.runtime.client.")}
    source = ROOT / "generated" / "drivemap_models" / "sdm630"
    package = tmp_path / "old_sdm630"
    package.mkdir()
    rewritten = 0
    for path in source.glob("*.py"):
        text = path.read_text(encoding="utf-8")
        for new, old in old_of.items():
            rewritten += text.count(f"from {new} import")
            text = text.replace(f"from {new} import", f"from {old} import")
        (package / path.name).write_text(text, encoding="utf-8")
    assert rewritten >= 4  # bus, declare, codec, records
    sys.path.insert(0, str(tmp_path))
    try:
        for old in old_of.values():
            sys.modules.pop(old, None)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", DeprecationWarning)
            pkg = importlib.import_module("old_sdm630")
        assert any("drivemap.runtime.client.values.codec" in str(w.message) for w in caught)
        client = pkg.Client(pkg.Bus.tcp("127.0.0.1", 1), unit=1)
        assert client.plan() == importlib.import_module("drivemap_models.sdm630").Client.plan()
        assert sorted(n for n in dir(client) if n.startswith("_") and not n.startswith("__")) == ["_drivemap", "_is_protocol"]
        client.bus.close()
    finally:
        sys.path.remove(str(tmp_path))
        for name in [n for n in sys.modules if n == "old_sdm630" or n.startswith("old_sdm630.")]:
            del sys.modules[name]

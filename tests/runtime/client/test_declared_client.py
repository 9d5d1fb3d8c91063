"""The generated client declares each register once, as a documented class-level descriptor; the
runtime builds the same client from a spec without running generated text; the generated
``spec.py`` is :func:`spec_from_model`'s object printed."""

from __future__ import annotations

import ast
import importlib
import json
import pydoc
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from drivemap.backends.views.spec import print_spec
from drivemap.compiler import compile_map
from drivemap.model.spec import spec_from_model
from drivemap.runtime import spec as spec_module
from drivemap.runtime.client.api.accessors import AsyncReadOnly, ReadOnly, ReadWriteArray
from drivemap.runtime.client.api.declare import ReadOnlyReg, Reg
from drivemap.runtime.client.api.dynamic import client_package
from drivemap.runtime.package import load_package

ROOT = Path(__file__).resolve().parents[3]
MODELS = ["ev", "edx", "v2", "vfd1000", "sdm630", "fronius_symo_hybrid"]
TEST_MAPS = sorted((ROOT / "tests" / "maps").glob("*.yaml"))


@pytest.mark.parametrize("name", MODELS)
def test_built_spec_is_spec_from_model(name: str) -> None:
    built = importlib.import_module(f"drivemap_models.{name}.spec").SPEC
    assert built == spec_from_model(compile_map(ROOT / "maps" / f"{name}.yaml"))


@pytest.mark.parametrize("path", TEST_MAPS, ids=lambda p: p.stem)
def test_printed_spec_evaluates_to_the_same_object(path: Path) -> None:
    spec = spec_from_model(compile_map(path))
    namespace = {name: getattr(spec_module, name) for name in dir(spec_module) if name.endswith("Spec")}
    assert eval(print_spec(spec), namespace) == spec  # noqa: S307 - the test's own printout


@pytest.mark.parametrize("name", MODELS)
def test_help_shows_every_register_with_its_documentation(name: str) -> None:
    package = importlib.import_module(f"drivemap_models.{name}")
    text = pydoc.render_doc(package.Client, renderer=pydoc.plaintext)
    for reg in package.SPEC.registers:
        assert reg.name in text, reg.name
        doc = getattr(package.Client, reg.name).__doc__
        assert doc and f"Manual: {reg.source}." in doc
        if reg.unit:
            assert reg.unit in doc


def test_docstrings_carry_only_the_lines_that_apply() -> None:
    from drivemap_models.ev import Client
    from drivemap_models.sdm630 import Client as Meter

    assert "Unit: r/min" in (Client.motor_speed.__doc__ or "")
    for name in MODELS:
        package = importlib.import_module(f"drivemap_models.{name}")
        for reg in package.SPEC.registers:
            doc = (getattr(package.Client, reg.name).__doc__ or "").lower()
            # unknown reflect/storage is said of what can be written, not of read-only registers
            assert ("reflect: unknown" in doc) == (reg.writable and reg.reflect == "unknown"), reg.name
            assert ("storage: unknown" in doc) == (reg.writable and reg.storage == "unknown"), reg.name
            stated = re.search(r"range (—|-?[0-9.e+-]+) \.\. (—|-?[0-9.e+-]+)", doc) is not None
            assert stated == (reg.min is not None or reg.max is not None), reg.name
    assert "reflect" not in (Meter.phase_1_voltage.__doc__ or "")
    assert "Unit: none" not in (Meter.phase_1_voltage.__doc__ or "")
    shown = pydoc.render_doc(Client.motor_speed, renderer=pydoc.plaintext)
    assert "Current motor speed" in shown


def test_each_register_is_declared_once_and_bound_lazily() -> None:
    from drivemap.runtime.client.transport.bus import Bus
    from drivemap_models.ev import AsyncClient, Client
    from drivemap_models.ev import client as module

    source = (ROOT / "generated" / "drivemap_models" / "ev" / "client.py").read_text(encoding="utf-8")
    assert source.count("motor_speed:") == 2  # the descriptor and the snapshot field
    assert isinstance(vars(module._Registers)["motor_speed"], ReadOnlyReg)
    assert "motor_speed" not in vars(Client) and "motor_speed" not in vars(AsyncClient)
    drive = Client(Bus.tcp("127.0.0.1", 1))
    assert not any(isinstance(v, (ReadOnly, ReadWriteArray)) for v in vars(drive).values())  # nothing built yet
    speed = drive.motor_speed
    assert isinstance(speed, ReadOnly) and drive.motor_speed is speed and vars(drive)["motor_speed"] is speed
    assert "Current motor speed" in (speed.__doc__ or "")
    assert "Current motor speed" in pydoc.render_doc(speed, renderer=pydoc.plaintext)  # help(drive.motor_speed)
    assert list(drive.registers) == [r.name for r in Client.SPEC.registers]


async def test_the_async_client_binds_async_accessors() -> None:
    from drivemap.runtime.client.transport.bus import AsyncBus
    from drivemap_models.ev import AsyncClient

    drive = AsyncClient(AsyncBus.tcp("127.0.0.1", 1))
    assert isinstance(drive.motor_speed, AsyncReadOnly) and drive.motor_speed is drive.motor_speed


@pytest.mark.parametrize("name", MODELS)
def test_the_runtime_builds_the_same_client_from_the_spec(name: str) -> None:
    from drivemap.runtime.client.transport.bus import Bus

    built = importlib.import_module(f"drivemap_models.{name}")
    dynamic = client_package(built.SPEC, f"drivemap_test_dynamic_{name}")
    assert sorted(dynamic.EXCEPTIONS) == sorted(built.EXCEPTIONS)
    assert {c.__name__ for c in dynamic.EXCEPTIONS.values()} == {c.__name__ for c in built.EXCEPTIONS.values()}
    assert {k: type(v).__name__ for k, v in dynamic.CODECS.items()} == \
        {k: type(v).__name__ for k, v in built.CODECS.items()}
    assert hasattr(dynamic, "BroadcastClient") == hasattr(built, "BroadcastClient")
    a, b = built.Client(Bus.tcp("127.0.0.1", 1)), dynamic.Client(Bus.tcp("127.0.0.1", 1))
    assert [(n, type(x).__name__) for n, x in a.registers.items()] == \
        [(n, type(x).__name__) for n, x in b.registers.items()]
    for enum_spec in built.SPEC.enums:
        assert [(m.name, m.value) for m in getattr(built, enum_spec.name)] == \
            [(m.name, m.value) for m in getattr(dynamic, enum_spec.name)]


def test_load_package_runs_no_rendered_code() -> None:
    """The live verbs' and the gateway's package comes from the spec: building it loads no back end
    or template module and renders nothing (jinja2's rendering is made to fail)."""
    code = textwrap.dedent("""
        import sys
        from drivemap.compiler import compile_map
        from drivemap.model.spec import spec_from_model
        from drivemap.runtime.package import load_package
        model = compile_map("maps/ev.yaml")
        import jinja2
        def refuse(*args, **kwargs):
            raise AssertionError("rendered")
        jinja2.Template.render = refuse
        jinja2.Environment.get_template = refuse
        before = set(sys.modules)
        package = load_package(spec_from_model(model))
        assert package.Client.SPEC.name == "ev" and package.simulator.Simulator.SPEC is package.SPEC
        print(sorted(m for m in set(sys.modules) - before if m.startswith(("drivemap.backends", "jinja2"))))
    """)
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120,
                         env={"PYTHONPATH": f"{ROOT / 'generator'}:{ROOT / 'generated'}", "PATH": "/usr/bin:/bin"})
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


def test_no_module_executes_generated_text() -> None:
    """``exec``/``compile`` appear only in the read-program compiler (programs made from a read plan,
    no map or template text); the in-memory package is built, not rendered and run."""
    found = []
    for path in sorted((ROOT / "generator" / "drivemap").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ("exec", "compile"):
                found.append(f"{path.relative_to(ROOT)}:{node.func.id}")
    assert found == ["generator/drivemap/runtime/client/protocol/programs.py:exec",
                     "generator/drivemap/runtime/client/protocol/programs.py:compile"]


def test_reg_descriptor_refuses_nothing_it_should_not() -> None:
    """A descriptor read from the class is itself (its docstring for ``help``), not an accessor."""
    from drivemap_models.ev import Client

    assert isinstance(Client.motor_speed, Reg)
    assert repr(Client.motor_speed) == "<ReadOnlyReg motor_speed>"


def test_in_memory_package_has_a_simulator() -> None:
    package = load_package(spec_from_model(compile_map(ROOT / "maps" / "v2.yaml")))
    sim = package.simulator.Simulator()
    assert sim.spec == package.SPEC


def test_codecs_are_made_on_first_use_and_kept() -> None:
    """Importing a client makes no codec; each is made once, on first use, and is the same object after;
    the mapping lists every register in map order, knows unknown names without making anything."""
    script = textwrap.dedent("""
        import json
        from drivemap_models import ev
        codecs = ev.CODECS
        before = repr(codecs)
        first = codecs["motor_speed"]
        print(json.dumps([before, first is codecs["motor_speed"], "motor_speed" in codecs, "nope" in codecs,
                          list(codecs) == [r.name for r in ev.SPEC.registers], len(codecs), repr(codecs)]))
    """)
    proc = subprocess.run([sys.executable, "-c", script], cwd=ROOT / "generated", capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    before, same, known, unknown, ordered, count, after = json.loads(proc.stdout)
    assert before == f"<Codecs of ev: {count} registers, 0 made>" and after.endswith(", 1 made>")
    assert (same, known, unknown, ordered) == (True, True, False, True)
    with pytest.raises(KeyError):
        importlib.import_module("drivemap_models.ev").CODECS["nope"]

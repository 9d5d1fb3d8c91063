"""Every catalogue map (``maps/catalogue/<source>/*.yaml``, imported from other projects' definitions) is
proven as the shipped maps are: it validates with build's checks, its generated package renders and is
valid Python, and its simulator, read back through its client over the in-process loopback, gives every
readable register the value the simulator holds. (The rebuild from ../shared is tests/onboard/importers/test_import_catalogue.py.)
"""

from __future__ import annotations

import contextlib
import warnings
from pathlib import Path

import pytest

from drivemap.backends.exporters.base import Options
from drivemap.backends.exporters.python import PythonExporter
from drivemap.build import build_checks
from drivemap.compiler import compile_cached
from drivemap.model.spec import spec_from_model
from drivemap.runtime.package import load_package
from drivemap.runtime.sim.simulator import Simulator, SimulatorError
from drivemap.testing.loopback import loopback_bus

ROOT = Path(__file__).resolve().parents[2]
CATALOGUE = sorted((ROOT / "maps" / "catalogue").rglob("*.yaml"))

pytestmark = pytest.mark.slow


def test_the_catalogue_holds_at_least_a_hundred_devices_each_with_its_source() -> None:
    import yaml

    assert len(CATALOGUE) >= 100
    for path in CATALOGUE:
        device = yaml.safe_load(path.read_text(encoding="utf-8"))["device"]
        assert device["evidence"] == "imported", path
        assert set(device["origin"]) >= {"project", "path", "commit", "licence"}, path


@pytest.mark.parametrize("path", CATALOGUE, ids=[f"{p.parent.name}/{p.stem}" for p in CATALOGUE])
def test_catalogue_map_builds_and_reads_back_its_simulator(path: Path, tmp_path: Path,
                                                           monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(ROOT)
    model = compile_cached(path.relative_to(ROOT), build_checks())
    files = PythonExporter().render(model, Options(package="catalogue_probe", root=ROOT, out=tmp_path,
                                                   docs=tmp_path / "docs"))
    for name, text in files.items():
        compile(text, name, "exec")  # the generated package is Python
    spec = spec_from_model(model)
    unit = spec.protocol.unit_min or 1
    sim = Simulator(spec, [unit])
    package = load_package(spec)
    readable = [r for r in model.registers if r.readable and r.page is None and r.scale_register is None]
    held = sim.unit(unit)
    factors = {r.scale_register for r in model.registers if r.scale_register}
    for reg in readable:  # a value of its own in each register, so a read of the wrong words shows
        if (reg.count == 1 and reg.type not in ("string", "bool", "f32", "f64") and not reg.enum and not reg.values
                and reg.name not in factors):
            with contextlib.suppress(SimulatorError):
                held.set_raw(reg.name, 1 + (reg.address * 7 + 3) % 250)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # registers under review warn on read; that is their point
        with loopback_bus(sim) as bus:
            client = package.Client(bus, unit=unit)
            snapshot = client.read_all()  # the planner's reads of the whole map, decoded
            raws = {reg.name: getattr(client, reg.name).read_raw() for reg in readable if reg.count == 1}
    assert readable, "a catalogue map reads something"
    for name, raw in raws.items():
        assert raw == held.raw(name), name  # the words the simulator holds, read back through the client
        value = getattr(snapshot, name)
        assert value is not None or model.register(name).not_available, name

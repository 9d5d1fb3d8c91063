"""mypy --strict accepts correct use of the generated API and rejects misuse."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]

GOOD = """
from drivemap_models.ev import AsyncClient, Client, MotorState, NetIn, ScCcMode, Snapshot


def use(drive: Client) -> None:
    drive.digital_speed_ram[0].write(1000)
    drive.net_in.write(NetIn.X0)
    drive.sc_cc_mode.write(ScCcMode(0))
    state: MotorState = drive.motor_state.read()
    speed: int = drive.motor_speed.read()
    snap: Snapshot = drive.read(drive.motor_state, drive.motor_speed)
    assert snap.motor_state is MotorState.RUN or state is MotorState.STOP or speed
    values: tuple[int, ...] = drive.digital_speed_ram.read()
    first: int = snap[drive.motor_speed]
    drive.read_modify_write(drive.net_in, lambda v: v | NetIn.X1)
    print(values, first, drive.read_by_name("digital_speed[0]"))


async def ause(drive: AsyncClient) -> None:
    await drive.digital_speed_ram[0].write(1000)
    state: MotorState = await drive.motor_state.read()
    print(state)
"""

BAD = """
from drivemap_models.ev import Client, MotorState


def misuse(drive: Client) -> None:
    drive.digital_speed_ram[0].write("1000")
    drive.sc_cc_mode.write(1)
    drive.motor_state.write(MotorState.RUN)
"""


def _mypy(tmp_path: Path, name: str, text: str) -> subprocess.CompletedProcess[str]:
    path = tmp_path / name
    path.write_text(textwrap.dedent(text), encoding="utf-8")
    return subprocess.run(
        [sys.executable, "-m", "mypy", "--strict", "--no-incremental", "--config-file", str(ROOT / "pyproject.toml"),
         str(path)],
        cwd=ROOT, capture_output=True, text=True, timeout=300,
    )


def test_mypy_accepts_good_and_rejects_misuse(tmp_path: Path) -> None:
    good = _mypy(tmp_path, "good_use.py", GOOD)
    assert good.returncode == 0, good.stdout + good.stderr
    bad = _mypy(tmp_path, "misuse.py", BAD)
    assert bad.returncode == 1, bad.stdout
    lines = [line for line in bad.stdout.splitlines() if ": error:" in line]
    # one error per misuse line: str to a numeric register, int where an enum is required, write on read-only
    assert any(":6:" in line and '"str"' in line for line in lines), bad.stdout
    assert any(":7:" in line and '"int"' in line and "ScCcMode" in line for line in lines), bad.stdout
    assert any(":8:" in line and "write" in line for line in lines), bad.stdout
    assert len(lines) == 3, bad.stdout


ALLKINDS_GOOD = """
from allkinds import AsyncClient, Client, GridState, Snapshot


def use(drive: Client) -> None:
    voltage: float = drive.phase_1_voltage.read()
    energy: float = drive.total_energy.read()
    counter: int = drive.energy_counter.read()
    net: int = drive.net_energy.read()
    serial: str = drive.serial_number.read()
    running: bool = drive.run.read()
    door: bool = drive.door_open.read()
    alarms: tuple[bool, ...] = drive.alarms.read()
    temperature: float | None = drive.temperature.read()
    state: GridState | None = drive.grid_state.read()
    power: float = drive.active_power.read()
    limit: float | None = drive.power_limit.read()
    drive.power_limit.write(None)
    drive.power_limit.write(50.0)
    drive.device_name.write("PUMP-7")
    drive.counter_preset.write(2**64 - 1)
    drive.run.write(True)
    drive.relays.write([True, False, True, False])
    drive.setpoint.write(12.5)
    drive.enable.write(False)
    drive.fault_reset.write(True)
    snap: Snapshot = drive.read(drive.temperature, drive.serial_number)
    maybe: float | None = snap[drive.temperature]
    print(voltage, energy, counter, net, serial, running, door, alarms, temperature, state, power, limit, maybe,
          sorted(drive.holes), drive.stats.split_reads + drive.stats.extra_requests)


async def ause(drive: AsyncClient) -> None:
    name: str = await drive.serial_number.read()
    await drive.run.write(False)
    print(name)
"""

ALLKINDS_BAD = """
from allkinds import Client


def misuse(drive: Client) -> None:
    temperature: float = drive.temperature.read()
    drive.serial_number.write("x")
    drive.device_name.write(5)
    drive.run.write(1)
    drive.setpoint.write(None)
    energy: int = drive.total_energy.read()
    drive.door_open.write(True)
    print(temperature, energy)
"""


def test_mypy_strict_on_a_generated_package_with_every_type(tmp_path: Path) -> None:
    """The generated code of tests/maps/allkinds.yaml (every type, Optional where not_available) passes
    mypy --strict, as does code using it; misuse of the new types is rejected."""
    from drivemap.backends.exporters.base import Options
    from drivemap.backends.exporters.python import PythonExporter
    from drivemap.compiler import compile_map

    model = compile_map(ROOT / "tests" / "maps" / "allkinds.yaml")
    files = PythonExporter().render(model, Options())
    for rel, text in files.items():
        target = tmp_path / rel
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(text, encoding="utf-8")
    client = (tmp_path / "allkinds" / "client.py").read_text(encoding="utf-8")
    # each register is declared once, at class level: ``name: ReadOnlyReg[float | None] = ...``
    optional = {line.split(":")[0].strip() for line in client.splitlines()
                if line.startswith("    ") and "Reg[" in line.split("=")[0] and "| None]" in line.split("=")[0]}
    assert optional == {r.name for r in model.registers if r.not_available}, "Optional only where not_available"
    env_path = str(tmp_path)
    good = _mypy_in(tmp_path, "good_allkinds.py", ALLKINDS_GOOD, env_path, extra=[str(tmp_path / "allkinds")])
    assert good.returncode == 0, good.stdout + good.stderr
    bad = _mypy_in(tmp_path, "bad_allkinds.py", ALLKINDS_BAD, env_path)
    assert bad.returncode == 1, bad.stdout
    lines = [line for line in bad.stdout.splitlines() if ": error:" in line]
    for number in (6, 7, 8, 9, 10, 11, 12):
        assert any(f":{number}:" in line for line in lines), (number, bad.stdout)
    assert len(lines) == 7, bad.stdout


def _mypy_in(tmp_path: Path, name: str, text: str, mypy_path: str,
             extra: list[str] | None = None) -> subprocess.CompletedProcess[str]:
    import os

    path = tmp_path / name
    path.write_text(textwrap.dedent(text), encoding="utf-8")
    env = dict(os.environ, MYPYPATH=mypy_path)
    return subprocess.run(
        [sys.executable, "-m", "mypy", "--strict", "--no-incremental", "--config-file", str(ROOT / "pyproject.toml"),
         str(path), *(extra or [])],
        cwd=ROOT, capture_output=True, text=True, timeout=300, env=env,
    )

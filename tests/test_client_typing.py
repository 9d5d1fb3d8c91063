"""mypy --strict accepts correct use of the generated API and rejects misuse."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

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

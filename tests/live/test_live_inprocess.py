"""``helpers_live.run`` (the CLI's ``main`` in the test's process, which the default tier's command-line
tests use) answers as the real command does: the same exit code, stdout and stderr as ``cli`` (a
``python -m drivemap`` subprocess), and a verb that would run on is stopped at its time bound."""

from __future__ import annotations

import time

import pytest
from helpers_client import tcp_server
from helpers_live import ROOT, CommandTimeout, cli, run

CASES = [
    ("--help",),
    ("bogus",),
    ("export", "--format", "homeassistant", "--help"),
    ("export", "ev", "--format", "homeassistant", "--bogus"),
    ("validate", "maps/ev.yaml"),
    ("validate", "tests/bad_maps/bad_access_mode.yaml"),
    ("export", "sdm630", "--format", "csv"),
    ("write", "ev", "--dry-run", "--tcp", "127.0.0.1:9", "digital_speed[3]=300", "digital_speed[0]=100"),
    ("write", "ev", "--dry-run", "--tcp", "127.0.0.1:9", "digital_accel_time[0]=1.25"),
    ("read", "ev", "--tcp", "127.0.0.1:9", "motor_state"),
    ("simulate", "sdm630", "--tcp", "127.0.0.1:0", "--set", "system_typ=3"),
]


@pytest.mark.parametrize("argv", CASES, ids=[" ".join(c)[:50] for c in CASES])
def test_in_process_main_answers_as_the_command(argv: tuple[str, ...]) -> None:
    inside, outside = run(*argv), cli(*argv)
    assert (inside.returncode, inside.stdout, inside.stderr) == (outside.returncode, outside.stdout, outside.stderr)


def test_in_process_main_answers_as_the_command_at_a_device() -> None:
    with tcp_server("sdm630") as (_, host, port):
        for argv in (("read", "sdm630", "--tcp", f"{host}:{port}", "phase_1_voltage", "frequency"),
                     ("scan", "--tcp", f"{host}:{port}", "--units", "1", "--json")):
            inside, outside = run(*argv), cli(*argv)
            assert (inside.returncode, inside.stdout, inside.stderr) == (
                outside.returncode, outside.stdout, outside.stderr), argv


def test_a_verb_that_runs_on_is_stopped_at_the_time_bound() -> None:
    started = time.monotonic()
    with pytest.raises(CommandTimeout, match="still runs after 1 s"):
        run("simulate", "ev", "--tcp", "127.0.0.1:0", timeout=1, cwd=ROOT)
    assert time.monotonic() - started < 30
    assert run("validate", "maps/ev.yaml").returncode == 0  # the next command runs as before

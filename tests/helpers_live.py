"""Helpers for the live-verb tests: the real CLI in a subprocess (:func:`cli`) or its ``main()`` in this
process (:func:`run`), simulators (in this process or as ``drivemap simulate`` subprocesses, possibly of
deliberately wrong maps), on 127.0.0.1 only."""

from __future__ import annotations

import contextlib
import io
import os
import re
import selectors
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from unittest import mock

ROOT = Path(__file__).resolve().parent.parent
ENV = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT / "generator"), str(ROOT / "generated"), str(ROOT)]),
           COLUMNS="200")


def cli(*args: str, timeout: float = 90, cwd: Path = ROOT, prefix: tuple[str, ...] = ()) -> subprocess.CompletedProcess[str]:
    """``python -m drivemap ARGS`` in a subprocess (stdout is a pipe, not a terminal)."""
    return subprocess.run([*prefix, sys.executable, "-m", "drivemap", *args], capture_output=True, text=True,
                          timeout=timeout, cwd=cwd, env=ENV)


class CommandTimeout(BaseException):
    """:func:`run`'s time bound ran out (a ``BaseException``, so no verb's error handling reports it as its own)."""


def run(*args: str, timeout: float = 90, cwd: Path = ROOT) -> subprocess.CompletedProcess[str]:
    """``drivemap ARGS`` as :func:`cli` runs it, but ``drivemap.cli.main`` in this process: the same exit
    code, stdout and stderr (the environment's ``COLUMNS`` as :data:`ENV` sets it, the working directory
    ``cwd``, ``sys.argv``), without starting an interpreter. An exception ``main`` lets escape propagates
    (a subprocess would print its traceback); an ``argparse`` exit becomes the exit code; a verb still
    running after ``timeout`` seconds is interrupted with :class:`CommandTimeout` (as :func:`cli`'s
    ``subprocess.TimeoutExpired``)."""
    from drivemap.cli import main

    def expire(_signum: int, _frame: object) -> None:
        raise CommandTimeout(f"drivemap {' '.join(args)} still runs after {timeout} s")

    out, err = io.StringIO(), io.StringIO()
    old = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, timeout)
    try:
        with (contextlib.chdir(cwd), mock.patch.dict(os.environ, {"COLUMNS": ENV["COLUMNS"]}),
              mock.patch.object(sys, "argv", [str(ROOT / "generator" / "drivemap" / "__main__.py"), *args]),
              contextlib.redirect_stdout(out), contextlib.redirect_stderr(err)):
            try:
                code: int | str | None = main(list(args))
            except SystemExit as exit_:
                code = exit_.code
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
    if isinstance(code, str):  # sys.exit("message"): printed to stderr, exit status 1
        err.write(code + "\n")
        code = 1
    return subprocess.CompletedProcess(["drivemap", *args], code or 0, out.getvalue(), err.getvalue())


def no_traceback(proc: subprocess.CompletedProcess[str]) -> None:
    assert "Traceback" not in proc.stderr and "Traceback" not in proc.stdout, proc.stderr


@contextlib.contextmanager
def simulate(model: str, *extra: str) -> Iterator[int]:
    """``drivemap simulate MODEL --tcp 127.0.0.1:0``: yields the port it listens on."""
    proc = subprocess.Popen([sys.executable, "-m", "drivemap", "simulate", model, "--tcp", "127.0.0.1:0", *extra],
                            cwd=ROOT, env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        sel = selectors.DefaultSelector()
        sel.register(proc.stdout, selectors.EVENT_READ)
        line = proc.stdout.readline() if sel.select(30) else ""
        sel.close()
        match = re.search(r"127\.0\.0\.1:(\d+)", line)
        assert match, (line, proc.stderr.read() if proc.poll() is not None and proc.stderr else "")
        yield int(match.group(1))
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=5)


def wrong_map(tmp_path: Path, name: str, edits: list[tuple[str, str]]) -> Path:
    """A copy of maps/ev.yaml with textual ``(old, new)`` edits: a "device" whose firmware differs."""
    text = (ROOT / "maps" / "ev.yaml").read_text(encoding="utf-8")
    for old, new in edits:
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    folder = tmp_path / name
    folder.mkdir()
    path = folder / "ev.yaml"
    path.write_text(text.replace("../schemas/", str(ROOT / "schemas") + "/"), encoding="utf-8")
    return path


def map_line(name: str) -> int:
    """The line of maps/ev.yaml where register ``name`` starts (its ``- name:`` line)."""
    for number, line in enumerate((ROOT / "maps" / "ev.yaml").read_text(encoding="utf-8").splitlines(), 1):
        if line.strip() == f"- name: {name}":
            return number
    raise KeyError(name)

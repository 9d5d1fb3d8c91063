"""Test tiers and the fixtures every tier shares.

Tiers (``pyproject.toml`` markers):

* the default tier (``pytest``): in-process tests (the compiler, the model, exporters, the runtime
  against the simulator's handler, the golden maps) -- minutes at most on a 2-core machine;
* ``slow`` (``pytest -m slow``): tests that start real servers, serial lines made of ptys, subprocesses,
  brokers or virtualenvs; which modules those are is listed below (:data:`SLOW_MODULES`), measured
  with ``pytest --durations=0``; single tests of a default-tier module that do so carry
  ``@pytest.mark.slow`` themselves, and an expensive search keeps a smaller default-tier twin (the
  full one is ``slow``). A command-line test whose subject is the verb's logic, not the process,
  calls ``drivemap.cli.main`` in this process (``tests/helpers_live.py``: ``run``);
* ``tools`` (``pytest -m tools``): third-party tools in virtualenvs of their own (ESPHome, Home
  Assistant, pymodbus.simulator); a tool that cannot be installed fails its test.

``.ci/run`` runs all three.
"""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path

import pytest

from tests.waits import free_port, wait_port, wait_until

#: The compile cache of this test session (inherited by the processes tests start): never the user's.
if not os.environ.get("DRIVEMAP_CACHE_DIR"):
    os.environ["DRIVEMAP_CACHE_DIR"] = tempfile.mkdtemp(prefix="drivemap-test-cache-")
    atexit.register(shutil.rmtree, os.environ["DRIVEMAP_CACHE_DIR"], True)

#: Test modules whose tests start real servers, ptys, subprocesses, brokers, type checkers or
#: virtualenvs, or run long property-based searches (``pytest --durations=0`` picked them).
SLOW_MODULES = frozenset({
    "test_cli", "test_client_faults", "test_client_serial", "test_client_typing", "test_compiler_fuzz", "test_docs",
    "test_escaping", "test_exporter_plugin", "test_injection", "test_project", "test_roundtrip",
    "test_serial_receiver", "test_simulator_fuzz", "test_simulator_server", "test_simulator_state",
    "test_simulator_tcp", "test_simulator_tcp_fuzz", "test_stale_replies", "test_vserial", "test_wheel",
    # the real command as a process: its stderr's encoding, a FIFO it must not hang on, a memory limit
    "test_cli_hostile", "test_map_bounds",
    # split off test_docs (links, leaks, escaping, the usage snippet against the simulator)
    "test_docs_links",
})
#: Every module of these families talks to real servers (the live verbs, the gateway, onboarding a device).
SLOW_PREFIXES = ("test_live_", "test_gateway_", "test_probe", "test_draft", "test_import")
#: ... except these, which check configurations and run in-process.
FAST_MODULES = frozenset({"test_gateway_config", "test_draft_corpus_score"})


def is_slow(module: str) -> bool:
    return module not in FAST_MODULES and (module in SLOW_MODULES or module.startswith(SLOW_PREFIXES))


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        if "tools" not in item.keywords and "corpus" not in item.keywords and is_slow(Path(str(item.fspath)).stem):
            item.add_marker(pytest.mark.slow)


@pytest.fixture
def port() -> int:
    """A free TCP port on 127.0.0.1."""
    return free_port()


@pytest.fixture
def until() -> Callable[..., bool]:
    """``until(predicate, timeout=5.0, step=0.02)``: poll a condition instead of sleeping."""
    return wait_until


@pytest.fixture
def listening() -> Callable[..., None]:
    """``listening(port, timeout=20.0, proc=None)``: wait for a server to accept connections."""
    return wait_port

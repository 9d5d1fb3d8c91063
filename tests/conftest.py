"""Test tiers and the fixtures every tier shares.

Tiers (``pyproject.toml`` markers):

* the default tier (``pytest``): in-process tests (the compiler, the model, exporters, the runtime
  against the simulator's handler, the golden maps) -- minutes at most on a 2-core machine;
* ``slow`` (``pytest -m slow``): tests that start real servers, serial lines made of ptys, subprocesses,
  brokers or virtualenvs; which modules those are is listed below (:data:`SLOW_MODULES`), measured
  with ``pytest --durations=0``;
* ``tools`` (``pytest -m tools``): third-party tools in virtualenvs of their own (ESPHome, Home
  Assistant, pymodbus.simulator); a tool that cannot be installed fails its test.

``.ci/run`` runs all three.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from tests.waits import free_port, wait_port, wait_until

#: Test modules whose tests start real servers, ptys, subprocesses, brokers or virtualenvs.
SLOW_MODULES = frozenset({
    "test_bad_maps_slow",
})


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        if Path(str(item.fspath)).stem in SLOW_MODULES and "tools" not in item.keywords:
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

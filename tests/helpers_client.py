"""Shared helpers for the client tests: real servers (the generated simulators) on 127.0.0.1 and
on a virtual serial line, and access to the generated packages."""

from __future__ import annotations

import contextlib
import importlib
from collections.abc import Iterator
from types import ModuleType
from typing import Any

from drivemap.runtime.sim.serve import ThreadedSimServer
from drivemap.testing.vserial import VirtualSerialLine

MODELS = ("edx", "ev", "v2", "vfd1000")
TIMEOUT = 0.3  # response timeout for tests (seconds); every test is bounded


def package(model: str) -> ModuleType:
    return importlib.import_module(f"drivemap_models.{model}")


def simulator(model: str, units: tuple[int, ...] = (1,)) -> Any:
    return importlib.import_module(f"drivemap_models.{model}.simulator").Simulator(units=list(units))


@contextlib.contextmanager
def tcp_server(model: str, units: tuple[int, ...] = (1,), *, sim: Any = None) -> Iterator[tuple[Any, str, int]]:
    """The model's simulator served over Modbus TCP on an ephemeral port: (sim, host, port)."""
    sim = sim if sim is not None else simulator(model, units)
    with ThreadedSimServer(sim, tcp=("127.0.0.1", 0)) as server:
        assert server.address is not None
        host, port = server.address
        yield sim, host, port


@contextlib.contextmanager
def serial_server(model: str, mode: str, units: tuple[int, ...] = (1,), *, baudrate: int = 38400,
                  sim: Any = None) -> Iterator[tuple[Any, VirtualSerialLine]]:
    """The model's simulator on the device end of a virtual serial line: (sim, line)."""
    sim = sim if sim is not None else simulator(model, units)
    with VirtualSerialLine(baudrate) as line:
        with ThreadedSimServer(sim, serial=line.device_port, mode=mode, baudrate=baudrate, parity="none",
                               stop_bits=1, data_bits=8):
            yield sim, line


def serial_mode(model: str, mode: str) -> bool:
    return mode in package(model).SPEC.protocol.modes

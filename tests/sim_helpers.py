"""pymodbus's simulator serving a ``pymodbus-sim`` export, and the generated client reading it back."""

from __future__ import annotations

import asyncio
import contextlib
import json
import threading
from collections.abc import Iterator
from typing import Any

from drivemap.backends.exporters.base import Options
from drivemap.backends.exporters.pymodbus_sim import PymodbusSimExporter
from drivemap.model.nodes import Model
from drivemap.model.spec import spec_from_model
from drivemap.runtime.package import load_package
from drivemap.runtime.sim.simulator import Simulator
from tests.waits import free_port, wait_port


def export(model: Model, port: int, **values: Any) -> dict[str, Any]:
    text = PymodbusSimExporter().render(model, Options(values={"tcp": f"127.0.0.1:{port}", **values}))
    doc: dict[str, Any] = json.loads(next(iter(text.values())))
    return doc


@contextlib.contextmanager
def serve_export(model: Model) -> Iterator[tuple[int, int]]:
    """The export served by pymodbus's ModbusSimulatorContext + ModbusTcpServer, set up from the
    JSON the way ``pymodbus.simulator`` (server/simulator/http_server.py) sets them up."""
    from pymodbus.datastore import ModbusServerContext, ModbusSimulatorContext
    from pymodbus.server import ModbusTcpServer

    port = free_port()
    doc = export(model, port)
    server_cfg = dict(doc["server_list"][model.name])
    server_cfg["address"] = (server_cfg.pop("host"), server_cfg.pop("port"))
    unit = int(server_cfg.pop("device_id"))
    context = ModbusSimulatorContext(doc["device_list"][model.name], None)
    store = ModbusServerContext(devices={unit: context}, single=False)
    server_cfg.pop("comm")
    framer = server_cfg.pop("framer")
    loop = asyncio.new_event_loop()
    thread = threading.Thread(target=loop.run_forever, daemon=True)
    thread.start()

    async def start() -> Any:
        server = ModbusTcpServer(store, framer=framer, **server_cfg)
        asyncio.get_running_loop().create_task(server.serve_forever())
        return server

    server = asyncio.run_coroutine_threadsafe(start(), loop).result(5)
    try:
        wait_port(port, 10.0)
        yield port, unit
    finally:
        asyncio.run_coroutine_threadsafe(server.shutdown(), loop).result(5)
        loop.call_soon_threadsafe(loop.stop)
        thread.join(5)
        loop.close()


def read_back(model: Model, port: int, unit: int) -> tuple[dict[str, Any], dict[str, Any]]:
    """(what the generated client reads from the server at ``port``, what it reads from drivemap's
    own simulator of the same map) for every readable register on the served page, in one batched
    read each (both at power-up: the export is the image drivemap's simulator starts with)."""
    from drivemap.runtime.sim.serve import ThreadedSimServer

    package = load_package(spec_from_model(model))
    names = [r.name for r in model.registers if r.readable and (r.page is None or _page_default(model, r) == r.page.value)]

    def read(at: int) -> dict[str, Any]:
        with package.Client.tcp("127.0.0.1", at, unit, timeout=2.0) as client:
            snap = client.read(*[client.accessor(n) for n in names])
            return {n: getattr(snap, n) for n in names}

    from drivemap.runtime.sim.behaviours import behaviour_for

    got = read(port)
    own_sim = Simulator(package.SPEC, [unit], behaviour=behaviour_for(model.name))  # as `drivemap simulate` starts
    with ThreadedSimServer(own_sim, tcp=("127.0.0.1", 0)) as own:
        assert own.address is not None
        expected = read(own.address[1])
    return got, expected


def _page_default(model: Model, reg: Any) -> int:
    shown = sorted({r.page.value for r in model.registers if r.page is not None and r.page.selector == reg.page.selector})
    default = model.register(reg.page.selector).default_at(0)
    return int(default) if default is not None and int(default) in shown else shown[0]

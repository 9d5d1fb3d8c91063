"""The running gateway: packages in memory, one bus and one task per line, the MQTT and OPC UA sides.

``drivemap gateway CONFIG.yaml`` loads the configuration (:func:`drivemap.gateway.config.load_config`),
builds each model's client package from its spec (:func:`drivemap.runtime.package.load_package`: no rendered code), one
:class:`~drivemap.runtime.client.transport.bus.AsyncBus` per configured bus with an ``AsyncClient`` per device on it,
and runs every :class:`~drivemap.gateway.lines.Line` in parallel with the MQTT bridge and the OPC UA
server until SIGINT/SIGTERM.
"""

from __future__ import annotations

import asyncio
import logging
from typing import Any

from drivemap.gateway.config import BusConfig, GatewayConfig
from drivemap.gateway.device import Command, Device
from drivemap.gateway.lines import Fanout, Line
from drivemap.model.nodes import Model
from drivemap.model.spec import spec_from_model
from drivemap.runtime.client.transport.bus import AsyncBus
from drivemap.runtime.package import load_package

log = logging.getLogger("drivemap.gateway")


def make_bus(cfg: BusConfig, package: Any) -> AsyncBus:
    """The AsyncBus of a configured bus (serial defaults from the first device's map)."""
    if cfg.kind == "tcp":
        assert cfg.host is not None and cfg.port is not None
        return AsyncBus.tcp(cfg.host, cfg.port, timeout=cfg.timeout, retries=cfg.retries)
    if cfg.kind == "rtu_over_tcp":
        assert cfg.host is not None and cfg.port is not None
        return AsyncBus.rtu_over_tcp(cfg.host, cfg.port, timeout=cfg.timeout, retries=cfg.retries)
    assert cfg.serial is not None
    overrides = {k: v for k, v in cfg.serial.items() if k != "port"}
    return AsyncBus.serial(cfg.serial["port"], package.SPEC.protocol.serial, timeout=cfg.timeout, retries=cfg.retries,
                           **overrides)


#: Seconds a stopping task gets before it is cancelled again (more than the MQTT bridge's own bounded goodbye).
STOP_GRACE = 5.0


async def stop_tasks(tasks: list[asyncio.Task[Any]], grace: float = STOP_GRACE) -> None:
    """Cancel ``tasks`` and wait until every one has ended.

    No task is left behind: an abandoned task is closed by the garbage collector, its ``finally``
    blocks cut short (``coroutine ignored GeneratorExit``) and its connections left open. A task
    still running after ``grace`` seconds is named in the log and cancelled again (a cancellation
    that arrives as an operation finishes can be lost); each task bounds its own clean-up.
    """
    pending = {task for task in tasks if not task.done()}
    while pending:
        for task in pending:
            task.cancel()
        _, pending = await asyncio.wait(pending, timeout=grace)
        if pending:
            log.warning("still stopping after %.1f s: %s; cancelling again", grace,
                        ", ".join(sorted(task.get_name() for task in pending)))


class Gateway:
    """Everything one configuration runs; ``await gateway.run(stop)`` until ``stop`` is set."""

    def __init__(self, cfg: GatewayConfig) -> None:
        self.cfg = cfg
        self._packages: dict[str, Any] = {}
        self.sink = Fanout()
        self.lines: list[Line] = []
        self.devices: dict[str, Device] = {}
        self._line_of: dict[str, Line] = {}
        prefix = cfg.mqtt.prefix if cfg.mqtt else "drivemap"
        for bus_cfg in cfg.buses:
            bus = make_bus(bus_cfg, self.package(bus_cfg.devices[0].model))
            devices = [Device(d, self.package(d.model), bus, prefix) for d in bus_cfg.devices]
            line = Line(bus_cfg, bus, devices, self.sink, (cfg.backoff_min, cfg.backoff_max))
            self.lines.append(line)
            for dev in devices:
                self.devices[dev.name] = dev
                self._line_of[dev.name] = line
        self.mqtt: Any = None
        self.opcua: Any = None
        self.started = asyncio.Event()
        if cfg.mqtt is not None:
            from drivemap.gateway.mqtt import MqttBridge

            self.mqtt = MqttBridge(cfg.mqtt, cfg.name, self.devices, self.submit)
            self.sink.sinks.append(self.mqtt)
        if cfg.opcua is not None:
            from drivemap.gateway.opcua import OpcuaBridge

            self.opcua = OpcuaBridge(cfg.opcua, cfg.name, self.devices, self.submit)
            self.sink.sinks.append(self.opcua)

    def package(self, model: Model) -> Any:
        """The generated package of ``model``, built once per map."""
        key = model.path
        if key not in self._packages:
            self._packages[key] = load_package(spec_from_model(model))
        return self._packages[key]

    def submit(self, cmd: Command) -> None:
        """Queue a checked command on its device's line."""
        self._line_of[cmd.device.name].submit(cmd)

    async def run(self, stop: asyncio.Event | None = None) -> None:
        """Serve until ``stop`` is set (or a task fails); then stop every task."""
        stop = stop or asyncio.Event()
        if self.opcua is not None:
            await self.opcua.start()
        tasks = [asyncio.create_task(line.run(), name=f"line {line.name}") for line in self.lines]
        if self.mqtt is not None:
            tasks.append(asyncio.create_task(self.mqtt.run(), name="mqtt"))
        stopper = asyncio.create_task(stop.wait(), name="stop")
        self.started.set()
        try:
            done, _ = await asyncio.wait([*tasks, stopper], return_when=asyncio.FIRST_COMPLETED)
            for task in done:
                if task is not stopper and not task.cancelled() and task.exception() is not None:
                    raise task.exception()  # type: ignore[misc]
        finally:
            for line in self.lines:
                line.stopping = True
            if self.mqtt is not None:
                self.mqtt.stopping = True
            await stop_tasks([*tasks, stopper])
            if self.opcua is not None:
                await self.opcua.stop()

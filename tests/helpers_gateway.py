"""Real parts for the gateway tests: an MQTT broker process, an MQTT subscriber, a gateway in the loop.

The broker is mosquitto when it is on PATH (``.ci/run`` installs it), else the pure-Python amqtt
broker from the test extra (``DRIVEMAP_TEST_BROKER=amqtt`` forces it). Both listen on 127.0.0.1
only, on a free port, and can be stopped and started again on the same port (broker restarts).
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import shutil
import socket
import subprocess
import sys
import time
from collections.abc import AsyncIterator, Callable
from pathlib import Path
from typing import Any

import aiomqtt

from drivemap.gateway.config import GatewayConfig, load_config
from drivemap.gateway.service import Gateway


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def broker_kind() -> str:
    forced = os.environ.get("DRIVEMAP_TEST_BROKER")
    if forced:
        return forced
    return "mosquitto" if shutil.which("mosquitto") or os.path.exists("/usr/sbin/mosquitto") else "amqtt"


class Broker:
    """An MQTT broker in its own process on 127.0.0.1:``port``."""

    def __init__(self, folder: Path, kind: str | None = None) -> None:
        self.folder = folder
        self.kind = kind or broker_kind()
        self.port = free_port()
        self.proc: subprocess.Popen[bytes] | None = None

    def _command(self) -> list[str]:
        if self.kind == "mosquitto":
            conf = self.folder / "mosquitto.conf"
            conf.write_text(f"listener {self.port} 127.0.0.1\nallow_anonymous true\npersistence false\n")
            exe = shutil.which("mosquitto") or "/usr/sbin/mosquitto"
            return [exe, "-c", str(conf)]
        conf = self.folder / "amqtt.yaml"
        conf.write_text(
            f"listeners:\n  default:\n    type: tcp\n    bind: 127.0.0.1:{self.port}\n"
            "plugins:\n  amqtt.plugins.authentication.AnonymousAuthPlugin:\n    allow_anonymous: true\n")
        return [sys.executable, "-c", "from amqtt.scripts.broker_script import main; main()", "-c", str(conf)]

    def start(self, timeout: float = 15.0) -> Broker:
        log = open(self.folder / f"{self.kind}.log", "ab")  # noqa: SIM115 - closed with the process
        self.proc = subprocess.Popen(self._command(), stdout=log, stderr=subprocess.STDOUT)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError(f"{self.kind} exited: {(self.folder / f'{self.kind}.log').read_text()[-2000:]}")
            with contextlib.suppress(OSError), socket.create_connection(("127.0.0.1", self.port), 0.2):
                return self
            time.sleep(0.05)
        raise RuntimeError(f"{self.kind} did not listen on {self.port}")

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5)
        self.proc = None


class Subscriber:
    """An independent MQTT client recording every message (latest per topic, and in order)."""

    def __init__(self, port: int, topics: tuple[str, ...] = ("#",)) -> None:
        self.port = port
        self.topics = topics
        self.latest: dict[str, bytes] = {}
        self.retained: dict[str, bool] = {}
        self.log: list[tuple[float, str, bytes]] = []
        self._task: asyncio.Task[None] | None = None
        self.ready = asyncio.Event()

    async def _run(self) -> None:
        while True:
            try:
                async with aiomqtt.Client("127.0.0.1", self.port, identifier=f"test-sub-{id(self)}") as client:
                    for t in self.topics:
                        await client.subscribe(t, qos=1)
                    self.ready.set()
                    async for m in client.messages:
                        payload = m.payload if isinstance(m.payload, bytes) else str(m.payload).encode()
                        self.latest[m.topic.value] = payload
                        self.retained[m.topic.value] = bool(m.retain)
                        self.log.append((time.monotonic(), m.topic.value, payload))
            except aiomqtt.MqttError:
                self.ready.clear()
                await asyncio.sleep(0.05)

    async def __aenter__(self) -> Subscriber:
        self._task = asyncio.create_task(self._run())
        await asyncio.wait_for(self.ready.wait(), 10)
        return self

    async def __aexit__(self, *exc: object) -> None:
        assert self._task is not None
        self._task.cancel()
        await asyncio.gather(self._task, return_exceptions=True)

    def text(self, topic: str) -> str | None:
        value = self.latest.get(topic)
        return None if value is None else value.decode()

    def messages(self, topic: str) -> list[bytes]:
        return [p for _, t, p in self.log if t == topic]


async def until(predicate: Callable[[], Any], timeout: float = 10.0, what: str = "condition") -> Any:
    """Poll ``predicate`` until it returns a truthy value; fail after ``timeout`` seconds."""
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout} s waiting for {what}")
        await asyncio.sleep(0.02)


async def publish(port: int, topic: str, payload: str, *, retain: bool = False) -> None:
    async with aiomqtt.Client("127.0.0.1", port, identifier=f"test-pub-{time.monotonic_ns()}") as client:
        await client.publish(topic, payload, qos=1, retain=retain)


def write_config(folder: Path, text: str) -> GatewayConfig:
    path = folder / "gateway.yaml"
    path.write_text(text)
    return load_config(path)


@contextlib.asynccontextmanager
async def running(cfg: GatewayConfig) -> AsyncIterator[Gateway]:
    """The gateway of ``cfg`` running in this event loop."""
    gateway = Gateway(cfg)
    stop = asyncio.Event()
    task = asyncio.create_task(gateway.run(stop))
    try:
        started = asyncio.create_task(gateway.started.wait())
        await asyncio.wait([started, task], timeout=30, return_when=asyncio.FIRST_COMPLETED)
        if task.done():
            task.result()  # raises what stopped the gateway
        yield gateway
    finally:
        stop.set()
        await asyncio.wait_for(task, 15)

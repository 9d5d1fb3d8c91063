"""The gateway's stop ends every task it started, with real parts (a mosquitto or amqtt broker
process, a simulator over TCP): none is left for the garbage collector to close.

A task left pending when its event loop closes is closed by the garbage collector later, while
some other code runs: the MQTT bridge's clean-up then awaits in a coroutine being closed ("coroutine
ignored GeneratorExit", "coroutine ... was never awaited"), and its connection stays open until then.
"""

from __future__ import annotations

import asyncio
import gc
import logging
import signal
import sys
import time
import warnings
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

from drivemap.gateway.config import GatewayConfig
from drivemap.gateway.mqtt import MqttBridge
from drivemap.gateway.service import Gateway, stop_tasks
from tests.helpers_client import tcp_server
from tests.helpers_gateway import Broker, until, write_config


@pytest.fixture
def broker(tmp_path: Path) -> Any:
    b = Broker(tmp_path).start()
    yield b
    b.stop()


def started_by_the_gateway(task: asyncio.Task[Any]) -> bool:
    """A task of :meth:`Gateway.run` (named so there) or of its MQTT bridge or lines."""
    return task.get_name() in ("mqtt", "stop") or task.get_coro().__qualname__.startswith(("MqttBridge.", "Line."))


def one_bus(tmp_path: Path, broker_port: int, vfd_port: int) -> GatewayConfig:
    return write_config(tmp_path, f"""\
gateway: 1
name: plant
mqtt: {{host: 127.0.0.1, port: {broker_port}, reconnect: {{min: 0.2, max: 0.5}}}}
buses:
  - name: line1
    tcp: 127.0.0.1:{vfd_port}
    timeout: 0.3
    devices:
      - {{name: pump1, model: vfd1000, unit: 1, interval: 0.2}}
""")


async def test_a_stop_that_comes_with_the_brokers_loss_ends_every_task(tmp_path: Path, broker: Broker) -> None:
    # The stop and the broker's end reach the bridge in the same turn of the loop: its TaskGroup
    # then reports the lost connection instead of the cancellation (Python 3.11). The bridge used
    # to take that for an outage and reconnect, and the gateway gave up on it after 10 s, leaving
    # the task running (and, once its loop closed, to the garbage collector).
    with tcp_server("vfd1000", (1,)) as (_, _, vport):
        gateway = Gateway(one_bus(tmp_path, broker.port, vport))
        stop = asyncio.Event()
        before = asyncio.all_tasks()
        run = asyncio.create_task(gateway.run(stop), name="gateway")
        try:
            await until(lambda: gateway.mqtt.connections == 1, what="gateway connected")
            await asyncio.sleep(0.5)  # the first values are out: the bridge waits for messages and values
            assert broker.proc is not None
            broker.proc.kill()
            broker.proc.wait(10)
            stop.set()
            time.sleep(0.3)  # the loop is held: the broker's end and the stop are seen together
            started = time.monotonic()
            await asyncio.wait_for(run, 30)
            took = time.monotonic() - started
            left = sorted(f"{t.get_name()} ({t.get_coro().__qualname__})" for t in asyncio.all_tasks() - before
                          if not t.done() and started_by_the_gateway(t))
            assert left == [], f"the gateway stopped and left {left} running"
            assert took < 3.0, f"the gateway took {took:.1f} s to stop"
            assert gateway.mqtt.failures == 0  # no reconnection attempt after the stop
        finally:
            leftovers = [t for t in asyncio.all_tasks() - before if not t.done() and t is not asyncio.current_task()]
            for task in leftovers:
                task.cancel()
            await asyncio.gather(*leftovers, return_exceptions=True)


async def test_a_broker_that_answers_nothing_does_not_hold_the_stop_up(tmp_path: Path, broker: Broker) -> None:
    # The broker process is frozen (SIGSTOP): the goodbye ("offline", the DISCONNECT) is never
    # acknowledged. The bridge bounds each (2 s), and the gateway still waits for its end.
    with tcp_server("vfd1000", (1,)) as (_, _, vport):
        gateway = Gateway(one_bus(tmp_path, broker.port, vport))
        stop = asyncio.Event()
        before = asyncio.all_tasks()
        run = asyncio.create_task(gateway.run(stop), name="gateway")
        assert broker.proc is not None
        try:
            await until(lambda: gateway.mqtt.connections == 1, what="gateway connected")
            broker.proc.send_signal(signal.SIGSTOP)
            started = time.monotonic()
            stop.set()
            await asyncio.wait_for(run, 30)
            took = time.monotonic() - started
            left = [t.get_name() for t in asyncio.all_tasks() - before if not t.done() and started_by_the_gateway(t)]
            assert left == [], f"the gateway stopped and left {left} running"
            assert took < 8.0, f"the gateway took {took:.1f} s to stop"
        finally:
            broker.proc.send_signal(signal.SIGCONT)
            leftovers = [t for t in asyncio.all_tasks() - before if not t.done() and t is not asyncio.current_task()]
            for task in leftovers:
                task.cancel()
            await asyncio.gather(*leftovers, return_exceptions=True)


async def test_stop_tasks_waits_for_a_task_that_lost_its_cancellation(caplog: pytest.LogCaptureFixture) -> None:
    ended: list[str] = []

    async def stubborn() -> None:
        try:
            await asyncio.sleep(30)
        except asyncio.CancelledError:
            pass  # what asyncio.wait_for or a TaskGroup can do with a cancellation on Python 3.11
        try:
            await asyncio.sleep(30)
        finally:
            await asyncio.sleep(0.05)  # its clean-up runs to the end
            ended.append("stubborn")

    task = asyncio.create_task(stubborn(), name="stubborn")
    await asyncio.sleep(0)
    with caplog.at_level(logging.WARNING, logger="drivemap.gateway"):
        await asyncio.wait_for(stop_tasks([task], grace=0.2), 5)
    assert task.done() and ended == ["stubborn"]
    assert "still stopping after 0.2 s: stubborn; cancelling again" in caplog.text


def drop_a_connected_bridge(cfg: GatewayConfig) -> None:
    """Run a bridge in a loop of its own until it is connected, then close that loop without
    cancelling the bridge (what pytest-asyncio before 1.0 did with a task left at a test's end):
    the task is dropped, for the garbage collector."""
    assert cfg.mqtt is not None
    mqtt = cfg.mqtt
    loop = asyncio.new_event_loop()
    tasks: list[asyncio.Task[None]] = []

    async def connected() -> None:
        bridge = MqttBridge(mqtt, "plant", {}, lambda cmd: None)
        tasks.append(asyncio.create_task(bridge.run(), name="dropped bridge"))
        await asyncio.wait_for(bridge.connected.wait(), 10)

    try:
        loop.run_until_complete(connected())
    finally:
        loop.close()
    assert not tasks[0].done()


async def test_a_dropped_bridge_is_closed_without_awaiting(tmp_path: Path, broker: Broker,
                                                           monkeypatch: pytest.MonkeyPatch) -> None:
    # Closed by the garbage collector (GeneratorExit), not cancelled, the bridge must not await in
    # its clean-up: it would run in whatever loop is current then (this test's), and Python reports
    # "coroutine ignored GeneratorExit" and "coroutine 'Client.__aexit__' was never awaited".
    cfg = one_bus(tmp_path, broker.port, 1)
    await asyncio.to_thread(drop_a_connected_bridge, cfg)
    unraisable: list[str] = []
    monkeypatch.setattr(sys, "unraisablehook", lambda u: unraisable.append(f"{u.object!r}: {u.exc_value}"))
    before = asyncio.all_tasks()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        gc.collect()
        await asyncio.sleep(0.1)  # anything the closing bridge started in this loop runs now
        gc.collect()
    started = [t.get_coro().__qualname__ for t in asyncio.all_tasks() - before]
    for task in asyncio.all_tasks() - before:
        task.cancel()
    # (paho's socket, collected with its closed loop, reports that loop closed: not the bridge's)
    assert not [u for u in unraisable if "GeneratorExit" in u or "MqttBridge" in u], unraisable
    assert not [str(w.message) for w in caught if "never awaited" in str(w.message)]
    assert not started, f"the closing bridge started {started} in another loop"


async def test_a_publish_acknowledged_as_the_stop_comes_does_not_keep_the_sender(tmp_path: Path,
                                                                                broker: Broker) -> None:
    # On Python 3.11 asyncio.wait_for (inside aiomqtt's publish) returns, instead of raising, when
    # the operation finished just before the cancellation came: the sender's cancellation is lost.
    # The owner's stopping flag still ends it (else the bridge's TaskGroup, and the stop, wait forever).
    cfg = one_bus(tmp_path, broker.port, 1)
    assert cfg.mqtt is not None
    bridge = MqttBridge(cfg.mqtt, "plant", {}, lambda cmd: None)
    async with bridge._client() as client:
        sender = asyncio.create_task(bridge._send(client))
        try:
            bridge.publish_outcome(SimpleNamespace(topic="drivemap/test"), {"ok": True})  # type: ignore[arg-type]
            for _ in range(10_000):  # turn by turn: the publish is sent, and its PUBACK read, in a few
                if client._pending_publishes:
                    break
                await asyncio.sleep(0)
            acknowledged = next(iter(client._pending_publishes.values()))
            for _ in range(100_000):
                if acknowledged.is_set():  # the broker's PUBACK has been read: the publish has finished
                    break
                await asyncio.sleep(0)
            assert acknowledged.is_set()
            bridge.stopping = True
            sender.cancel()
            await asyncio.wait([sender], timeout=2.0)
            assert sender.done(), "the sender went on after the stop"
        finally:
            sender.cancel()
            await asyncio.gather(sender, return_exceptions=True)

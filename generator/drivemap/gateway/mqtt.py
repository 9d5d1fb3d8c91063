"""The MQTT side of the gateway (aiomqtt): retained values, snapshots, availability, discovery, commands.

Topics (``P`` = the configured prefix, ``D`` = a device name):

* ``P/D/REGISTER``: the value in engineering units, retained, published when it changes (plain text
  for numbers and enum names, JSON for bit fields and arrays);
* ``P/D/state``: a JSON object of every published value of ``D``, retained, after every poll;
* ``P/D/availability``: ``online`` / ``offline`` (retained);
* ``P/gateway/NAME/availability``: the gateway's own ``online``, and ``offline`` as its last will
  (LWT) and on a clean stop;
* ``P/D/REGISTER/set`` and ``P/D/REGISTER/INDEX/set`` (array elements): commands. Retained
  commands are ignored (no replay of old commands after a restart). Every command's outcome, ok or
  the typed error, goes to ``P/D/error`` (not retained); a value outside a register's value set is
  answered with ``NotAllowedValue`` and the ``allowed`` values;
* Home Assistant discovery under the discovery prefix (:mod:`drivemap.gateway.discovery`), retained.

The bridge keeps the latest payload of every retained topic. While the broker is away, values keep
arriving and replace older ones, and outcomes queue; on every (re)connection the bridge publishes
the gateway's ``online``, all discovery and all retained state again, then the queued outcomes, so
nothing accepted before an outage is lost. Reconnection waits ``reconnect.min`` seconds, doubling
up to ``reconnect.max``.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
from collections import deque
from collections.abc import Callable, Iterable
from typing import Any

import aiomqtt

from drivemap.gateway.config import MqttConfig
from drivemap.gateway.device import Command, Device
from drivemap.gateway.discovery import discovery_messages
from drivemap.runtime.errors import DriveError, NotAllowedValue

log = logging.getLogger("drivemap.gateway.mqtt")

#: Retained publishes sent concurrently (each awaits its acknowledgement at QoS 1/2).
BATCH = 256
#: Outcomes kept while the broker is away (the oldest go first beyond this).
OUTBOX_LIMIT = 100_000
#: Characters of a refused payload echoed in its outcome.
MAX_SHOWN = 64


class _QuietPending(logging.Filter):
    """aiomqtt warns about every publish beyond ten in flight; the bridge sends batches on purpose."""

    def filter(self, record: logging.LogRecord) -> bool:
        return "pending publish calls" not in record.getMessage()


_CLIENT_LOG = logging.getLogger("drivemap.gateway.mqtt.client")
_CLIENT_LOG.addFilter(_QuietPending())


def payload_text(value: Any) -> str:
    """The payload of a value topic: numbers and names as plain text, structures as JSON."""
    if isinstance(value, str):
        return value
    return json.dumps(value, separators=(",", ":"), ensure_ascii=False)


class MqttBridge:
    """Publishes what the lines report and turns ``/set`` messages into checked commands."""

    def __init__(self, cfg: MqttConfig, gateway: str, devices: dict[str, Device],
                 submit: Callable[[Command], None]) -> None:
        self.cfg = cfg
        self.gateway = gateway
        self.devices = devices
        self.submit = submit
        self.availability_topic = f"{cfg.prefix}/gateway/{gateway}/availability"
        self.state: dict[str, str] = {}
        self._dirty: dict[str, str] = {}
        self._outbox: deque[tuple[str, str]] = deque(maxlen=OUTBOX_LIMIT)
        self._wake = asyncio.Event()
        self.connected = asyncio.Event()
        self.connections = 0
        self.failures = 0
        self.published = 0
        self.stopping = False  # set by the owner before it cancels run() (see there)
        if cfg.discovery:
            for dev in devices.values():
                for topic, payload in discovery_messages(gateway, dev, cfg.discovery_prefix, self.availability_topic,
                                                          cfg.ha_version):
                    self.state[topic] = json.dumps(payload, ensure_ascii=False, sort_keys=True)

    # ------------------------------------------------------------------ Sink
    def _retain(self, topic: str, payload: str) -> None:
        self.state[topic] = payload
        self._dirty[topic] = payload
        self._wake.set()

    def publish_values(self, device: Device, values: dict[str, Any], changed: dict[str, Any]) -> None:
        for name, value in changed.items():
            text = device.value_text(name, value)
            self._retain(f"{device.topic}/{name}", payload_text(value) if text is None else text)
        self._retain(f"{device.topic}/state", json.dumps(device.values, separators=(",", ":"), ensure_ascii=False))

    def publish_availability(self, device: Device, online: bool) -> None:
        self._retain(f"{device.topic}/availability", "online" if online else "offline")

    def publish_outcome(self, device: Device, outcome: dict[str, Any]) -> None:
        self._outbox.append((f"{device.topic}/error", json.dumps(outcome, ensure_ascii=False)))
        self._wake.set()

    # ------------------------------------------------------------------ connection
    def _client(self) -> aiomqtt.Client:
        cfg = self.cfg
        will = aiomqtt.Will(self.availability_topic, "offline", qos=1, retain=True)
        return aiomqtt.Client(cfg.host, cfg.port, identifier=cfg.client_id, username=cfg.username,
                              password=cfg.password, will=will, keepalive=cfg.keepalive, clean_session=True,
                              timeout=10.0, logger=_CLIENT_LOG)

    async def run(self) -> None:
        """Connect, serve, and reconnect with backoff, until cancelled.

        The owner sets :attr:`stopping` before it cancels, because a cancellation can be lost:
        ``asyncio.TaskGroup`` raises a child's error instead of it when both arrive together (the
        broker goes as the gateway stops), and on Python 3.11 ``asyncio.wait_for`` (in aiomqtt's
        publish) returns an operation that finished as it was cancelled. The flag still ends the loops.
        """
        delay = self.cfg.reconnect_min
        while not self.stopping:
            try:
                await self._connection()
                delay = self.cfg.reconnect_min
            except aiomqtt.MqttError as exc:
                if self.stopping:  # the stop came with the broker's loss (reported instead of the cancellation)
                    return
                self.failures += 1
                log.warning("MQTT broker %s:%d: %s; reconnecting in %.1f s", self.cfg.host, self.cfg.port, exc, delay)
            self.connected.clear()
            await asyncio.sleep(delay)
            delay = min(delay * 2, self.cfg.reconnect_max)

    async def _connection(self) -> None:
        client = self._client()
        await client.__aenter__()
        try:
            await self._session(client)
        except GeneratorExit:  # closed, not cancelled (its task was dropped): nothing can be awaited any more
            raise
        except BaseException:
            await self._disconnect(client)
            raise
        await self._disconnect(client)

    @staticmethod
    async def _disconnect(client: aiomqtt.Client) -> None:
        """End the connection; a broker that never acknowledges the disconnection does not hold the gateway up."""
        with contextlib.suppress(Exception, TimeoutError):
            await asyncio.wait_for(client.__aexit__(None, None, None), 2.0)

    async def _session(self, client: aiomqtt.Client) -> None:
        try:
            await self._serve(client)
        except asyncio.CancelledError:
            with contextlib.suppress(Exception):
                await asyncio.wait_for(client.publish(self.availability_topic, "offline", qos=1, retain=True), 2.0)
            raise

    async def _serve(self, client: aiomqtt.Client) -> None:
        prefix, qos = self.cfg.prefix, self.cfg.qos
        await client.subscribe(f"{prefix}/+/+/set", qos)
        await client.subscribe(f"{prefix}/+/+/+/set", qos)
        await client.publish(self.availability_topic, "online", qos=1, retain=True)
        self._dirty.clear()
        await self._publish_retained(client, list(self.state.items()))
        self.connections += 1
        self.connected.set()
        log.info("MQTT connected to %s:%d (%d retained topics published)", self.cfg.host, self.cfg.port,
                 len(self.state))
        try:
            async with asyncio.TaskGroup() as tasks:
                tasks.create_task(self._receive(client))
                tasks.create_task(self._send(client))
        except* aiomqtt.MqttError as group:
            raise group.exceptions[0] from None

    async def _publish_retained(self, client: aiomqtt.Client, items: Iterable[tuple[str, str]]) -> None:
        items = list(items)
        for start in range(0, len(items), BATCH):
            batch = items[start:start + BATCH]
            try:
                await asyncio.gather(*(client.publish(t, p, qos=self.cfg.qos, retain=True) for t, p in batch))
            except aiomqtt.MqttError:
                for t, p in batch:  # sent again after the reconnection (the newest value wins)
                    self._dirty.setdefault(t, p)
                raise
            self.published += len(batch)

    async def _send(self, client: aiomqtt.Client) -> None:
        while True:
            if self.stopping:  # a publish that completed as it was cancelled returned (wait_for, 3.11)
                return
            await self._wake.wait()
            self._wake.clear()
            while self._dirty or self._outbox:
                if self._dirty:
                    batch = list(self._dirty.items())[:BATCH]
                    for t, _ in batch:
                        del self._dirty[t]
                    await self._publish_retained(client, batch)
                while self._outbox:
                    topic, payload = self._outbox[0]
                    await client.publish(topic, payload, qos=max(1, self.cfg.qos))
                    self._outbox.popleft()
                    self.published += 1

    async def _receive(self, client: aiomqtt.Client) -> None:
        async for message in client.messages:
            raw = message.payload
            payload = raw if isinstance(raw, (bytes, bytearray)) else str(raw if raw is not None else "").encode()
            try:
                self.on_command(message.topic.value, bytes(payload), bool(message.retain))
            except Exception:  # noqa: BLE001 - no message may stop the bridge (on_command answers what it can)
                log.exception("MQTT message on %s could not be handled", message.topic.value)

    # ------------------------------------------------------------------ commands
    def on_command(self, topic: str, payload: bytes, retained: bool) -> None:
        parts = topic[len(self.cfg.prefix) + 1:].split("/")
        if parts[-1] != "set" or len(parts) not in (3, 4):
            return
        device = self.devices.get(parts[0])
        if retained:
            log.warning("ignoring retained command on %s (commands are never replayed)", topic)
            return
        if device is None:
            log.warning("command for unknown device on %s", topic)
            return
        target = parts[1] if len(parts) == 3 else f"{parts[1]}[{parts[2]}]"
        shown = payload[:MAX_SHOWN].decode("utf-8", "replace") + ("..." if len(payload) > MAX_SHOWN else "")
        try:
            cmd = device.command(target, payload, "mqtt")
            self.submit(cmd)
        except DriveError as exc:
            allowed = {"allowed": list(exc.allowed)} if isinstance(exc, NotAllowedValue) else {}
            self.publish_outcome(device, {"register": target, "value": shown, "ok": False, "source": "mqtt",
                                          "error": type(exc).__name__, "message": str(exc), **allowed})
        except Exception as exc:  # noqa: BLE001 - no message may stop the gateway: logged and answered
            log.exception("command on %s failed", topic)
            self.publish_outcome(device, {"register": target, "value": shown, "ok": False, "source": "mqtt",
                                          "error": "InternalError", "message": f"{type(exc).__name__}: the gateway "
                                          "could not handle this command (logged)"})

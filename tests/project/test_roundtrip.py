"""Round trips of every example frame printed in every manual, through client and simulator.

The tests are generated from the maps' ``examples``: a new map's examples are tested with no new
test code. For every example, in its mode (RTU or ASCII), on a virtual serial line:

1. **Encode** - the generated client, asked for the operation the example describes, puts exactly
   the printed request bytes on the line (captured on the line, not mocked).
2. **Serve** - the generated simulator, preset to the example's register values, answers exactly
   the printed response bytes (the corrected ones for an erratum); a broadcast gets no answer and
   changes every unit on the line.
3. **Decode** - the client turns the response into the documented engineering values or into the
   typed exception with the printed code.
4. **Errata** - a printed frame declared wrong is refused by the client (wrong checksum) or shown
   not to be Modbus (wrong layout), and the corrected frame is served and decoded; illegible frames
   check what is legible and say what is skipped.

Replies-only examples (the manual prints no request) are decoded from a scripted device that
answers the printed bytes.

Besides the project's maps, the synthetic maps in ``tests/maps/`` (every construct of the map
language, frames computed with pymodbus) run here too, through their generated package built in
memory (:func:`drivemap.runtime.package.load_package`: built from the spec, nothing rendered).
"""

from __future__ import annotations

import functools
import importlib
import math
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

from drivemap.compiler import compile_map, map_paths
from drivemap.frontend import frames
from drivemap.model.nodes import Example, Model
from drivemap.model.spec import spec_from_model
from drivemap.runtime.client.values.codec import EnumCodec, FieldsCodec, FlagCodec, unwrap
from drivemap.runtime.errors import DeviceException, TransportError
from drivemap.runtime.package import load_package
from drivemap.runtime.sim.serve import ThreadedSimServer
from drivemap.testing import VirtualSerialLine

TEST_MAPS = sorted((Path(__file__).resolve().parents[1] / "maps").glob("*.yaml"))
PROJECT: dict[str, Model] = {m.name: m for m in (compile_map(p) for p in map_paths())}
MODELS: dict[str, Model] = {**PROJECT, **{m.name: m for m in (compile_map(p) for p in TEST_MAPS)}}
CASES = [(m, ex) for m in MODELS.values() for ex in m.examples]
#: example ids run by this module, with the status seen (checked against the maps at the end)
SEEN: dict[str, str] = {}

SHORT_TIMEOUT = 0.4


def case_id(model: Model, ex: Example) -> str:
    section = ex.source.split(" ", 1)[-1].replace(" ", "_")
    return f"{model.name}-{section}-{ex.name}"


def wire(text: str, mode: str) -> bytes:
    """The bytes of a printed frame as they travel on the line."""
    return text.encode("ascii") if mode == "ascii" else bytes.fromhex(text)


@dataclass
class Exchange:
    requests: list[bytes]
    replies: list[bytes]
    result: Any
    error: BaseException | None


@functools.cache
def package(name: str) -> ModuleType:
    """The generated package of a model: built (``drivemap_models``) or, for tests/maps, in memory."""
    if name in PROJECT:
        return importlib.import_module(f"drivemap_models.{name}")
    return load_package(spec_from_model(MODELS[name]))


def serial_overrides(model: Model, mode: str) -> dict[str, Any]:
    """Settings for a pty line: the map's defaults where it has them, else explicit ones."""
    spec = package(model.name).SPEC.protocol.serial
    options: dict[str, Any] = {"mode": mode}
    if spec.baudrate is None:
        options["baudrate"] = 9600
    if spec.parity is None:
        options["parity"] = "N"
    if spec.stop_bits is None:
        options["stopbits"] = 1
    return options


def _typed(acc: Any, value: Any) -> Any:
    codec = unwrap(acc.codec)
    if value is None or isinstance(value, (str, bool)):
        return value
    if isinstance(codec, EnumCodec):
        return codec.enum_type(int(value))
    if isinstance(codec, FlagCodec):
        return codec.flag_type(int(value))
    if isinstance(codec, FieldsCodec):
        return codec.decode(int(value))
    return value


def _cells_at(model: Model, address: int, quantity: int) -> list[str]:
    names = []
    for cell in model.cells():
        if address <= cell.address < address + quantity and (cell.register.page is None or cell.register.page.value == 0):
            names.append(cell.name)
    return names


def _partial(model: Model, address: int, quantity: int) -> str | None:
    """The table of a read of ``quantity`` words at ``address`` that covers part of an element (the
    typed client reads whole elements only: such an example goes through ``read_registers``)."""
    for cell in model.cells():
        reg = cell.register
        if reg.page is not None and reg.page.value != 0:
            continue
        end = cell.address + reg.words
        if cell.address < address + quantity and address < end and not (address <= cell.address and end <= address + quantity):
            return reg.table
    return None


def _any_writable(model: Model) -> str | None:
    """A plain writable register to provoke a write's reply with; None when the map has none (a status page)."""
    for cell in model.cells():
        reg = cell.register
        if reg.writable and reg.page is None and not reg.bits and not reg.enum and reg.command_value is None:
            return cell.name
    return None


def _any_readable(model: Model) -> str:
    for cell in model.cells():
        if cell.register.readable and cell.register.page is None:
            return cell.name
    raise AssertionError("no readable register")


def perform(model: Model, ex: Example, client: Any) -> Any:
    """Ask the client for the operation the example describes."""
    meaning = ex.meaning
    values = dict(meaning.values)
    op = meaning.operation
    if op == "loopback":
        data = meaning.loopback[-1] if meaning.loopback else 0xA537
        return client.loopback(data)
    if op == "read" and not values and meaning.raw and _partial(model, meaning.address or 0, len(meaning.raw)):
        table = _partial(model, meaning.address or 0, len(meaning.raw))
        return {"raw": client.read_registers(table, meaning.address, len(meaning.raw))}
    if op == "read":
        names = list(values) or (_cells_at(model, meaning.address, meaning.quantity or 1)
                                 if meaning.address is not None else [_any_readable(model)])
        accessors = [client.accessor(n) for n in names]
        snapshot = client.read(*accessors)
        return {n: snapshot[a] for n, a in zip(names, accessors, strict=True)}
    if values:
        items = [(client.accessor(n), _typed(client.accessor(n), v)) for n, v in values.items()]
    elif meaning.raw:
        names = _cells_at(model, meaning.address or 0, len(meaning.raw))
        assert len(names) == len(meaning.raw), f"no registers at {meaning.address:#06x} for raw words"
        for name, raw in zip(names, meaning.raw, strict=True):
            client.accessor(name).write_raw(raw)
        return None
    else:
        name = _any_writable(model)
        if name is None:  # no writable register on the page the map covers: the printed reply's 06h by hand
            from pymodbus.pdu.register_message import WriteSingleRegisterRequest

            from drivemap.runtime.client.transport.exchange import Exchange

            pdu = WriteSingleRegisterRequest(address=model.registers[0].address, registers=[0])
            pdu.dev_id = meaning.unit
            reply = client.bus.exchange(Exchange(meaning.unit, pdu, model.protocol.timing, True, 0.0))
            client._drivemap.core.raise_for(reply, 0x06)  # the device's exception, as the client raises it
            return None
        acc = client.accessor(name)
        default = model.cell(name).register.default_at(model.cell(name).index)
        items = [(acc, _typed(acc, default if default is not None else 0))]
    if op == "write":
        assert len(items) == 1
        acc, value = items[0]
        acc.write(value)
    else:
        client.write_many(items)
    return None


def make_simulator(model: Model, ex: Example) -> Any:
    sim_module = importlib.import_module(f"{package(model.name).__name__}.simulator")
    units = [1, 2] if ex.meaning.broadcast else [ex.meaning.unit]
    sim = sim_module.Simulator(units)
    for name, value in ex.preset:
        sim.set(name, value, unit=None)
    return sim


def run_with_simulator(model: Model, ex: Example) -> tuple[Exchange, Any]:
    """Client on the master end, the generated simulator on the device end."""
    client_cls = package(model.name).Client
    sim = make_simulator(model, ex)
    if ex.inject_exception is not None:
        sim.inject_exception(ex.inject_exception)
    with VirtualSerialLine() as line:
        with ThreadedSimServer(sim, serial=line.device_port, mode=ex.mode, baudrate=9600):
            unit = ex.meaning.unit if not ex.meaning.broadcast else 1
            client = client_cls.serial(line.master_port, unit=unit, timeout=1.0, retries=0,
                                       **serial_overrides(model, ex.mode))
            with client:
                target = client_cls.broadcast(client.bus) if ex.meaning.broadcast else client
                result: Any = None
                error: BaseException | None = None
                try:
                    result = perform(model, ex, target)
                except (DeviceException, TransportError) as exc:
                    error = exc
            settle(line)
            exchange = Exchange(line.frames("to_device"), line.frames("to_master"), result, error)
    return exchange, sim


def settle(line: VirtualSerialLine) -> None:
    """Wait until what the client sent has crossed the line and the device had time to act on it."""
    line.wait_captured("to_device", 1, timeout=2.0)
    line.wait_delivered("to_device", len(line.captured("to_device")), timeout=2.0)
    line.wait_idle(2.0)
    threading.Event().wait(0.1)
    line.wait_idle(2.0)


class ScriptedDevice:
    """The device end answers every request with fixed bytes (to decode printed replies)."""

    def __init__(self, line: VirtualSerialLine, reply: bytes) -> None:
        self.port = line.open_serial("device", timeout=0.05)
        self.reply = reply
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        while not self.stop.is_set():
            data = self.port.read(256)
            if not data:
                continue
            while more := self.port.read(256):
                data += more
            self.port.write(self.reply)
            self.port.flush()

    def close(self) -> None:
        self.stop.set()
        self.thread.join(2.0)
        self.port.close()


def run_with_reply(model: Model, ex: Example, reply: bytes) -> Exchange:
    client_cls = package(model.name).Client
    with VirtualSerialLine() as line:
        device = ScriptedDevice(line, reply)
        try:
            client = client_cls.serial(line.master_port, unit=ex.meaning.unit, timeout=SHORT_TIMEOUT, retries=0,
                                       **serial_overrides(model, ex.mode))
            result: Any = None
            error: BaseException | None = None
            with client:
                try:
                    result = perform(model, ex, client)
                except (DeviceException, TransportError) as exc:
                    error = exc
        finally:
            device.close()
        settle(line)
        return Exchange(line.frames("to_device"), line.frames("to_master"), result, error)


def assert_decoded(model: Model, ex: Example, exchange: Exchange) -> None:
    meaning = ex.meaning
    if meaning.exception is not None:
        assert isinstance(exchange.error, DeviceException), f"expected exception {meaning.exception:#04x}, got {exchange.error!r}"
        assert exchange.error.code == meaning.exception
        known = {e.code for e in model.protocol.exceptions}
        if meaning.exception in known:
            assert type(exchange.error) is not DeviceException, "a listed code has its own typed error"
        return
    assert exchange.error is None, f"unexpected error: {exchange.error!r}"
    if meaning.operation == "read" and "raw" in (exchange.result or {}):
        assert exchange.result["raw"] == list(meaning.raw), f"raw words {exchange.result['raw']!r} != {meaning.raw!r}"
    if meaning.operation == "read":
        for name, expected in meaning.values:
            got = exchange.result[name]
            if expected is None or isinstance(expected, (str, bool)):
                assert got == expected and type(got) is type(expected), f"{name}: {got!r} != {expected!r}"
            elif isinstance(expected, int) and isinstance(got, int) and abs(expected) > 2**52:
                assert got == expected, f"{name}: {got!r} != {expected}"  # 64-bit integers, exactly
            else:
                assert math.isclose(float(got), expected, rel_tol=1e-9, abs_tol=1e-9), f"{name}: {got!r} != {expected}"
    if meaning.operation == "loopback":
        assert exchange.result == (meaning.loopback[-1] if meaning.loopback else 0xA537)


def legible(text: str | None, mode: str) -> bool:
    return text is not None and not frames.parse(text, mode).illegible


@pytest.mark.parametrize(("model", "ex"), CASES, ids=[case_id(m, e) for m, e in CASES])
def test_example_round_trip(model: Model, ex: Example) -> None:
    skipped: list[str] = []
    request = ex.wire_request
    response = ex.wire_response

    # 1-3 with the simulator: encode, serve, decode
    if request is not None and legible(request, ex.mode):
        exchange, sim = run_with_simulator(model, ex)
        assert exchange.requests, "the client put nothing on the line"
        assert exchange.requests[0] == wire(request, ex.mode), "encode: request differs from the manual"
        if ex.meaning.broadcast:
            assert exchange.replies == [], "serve: a broadcast got an answer"
            for name, value in ex.meaning.values:
                for unit in (1, 2):
                    got = sim.get(name, unit=unit)
                    assert got == value if isinstance(value, (str, bool)) or value is None else \
                        math.isclose(float(got), value), f"unit {unit}: {name} not written"
        elif response is not None and legible(response, ex.mode):
            assert exchange.replies, "serve: the simulator did not answer"
            assert exchange.replies[0] == wire(response, ex.mode), "serve: response differs from the manual"
            assert_decoded(model, ex, exchange)
            if ex.meaning.operation in ("write", "write_multiple") and ex.meaning.exception is None:
                for name, value in ex.meaning.values:  # the simulator decoded the written words as the client meant
                    got = sim.get(name, unit=ex.meaning.unit)
                    assert got == value if isinstance(value, (str, bool)) or value is None else \
                        math.isclose(float(got), value, rel_tol=1e-9), f"{name}: simulator holds {got!r}"
        else:
            skipped.append("serve/decode: response illegible")
    else:
        skipped.append("encode/serve: the manual prints no (legible) request")
        if response is not None and legible(response, ex.mode):
            exchange = run_with_reply(model, ex, wire(response, ex.mode))
            assert_decoded(model, ex, exchange)

    # 4: a printed frame declared wrong
    if ex.status == "erratum":
        assert ex.erratum
        for part, printed, corrected in (("request", ex.request, ex.corrected_request),
                                         ("response", ex.response, ex.corrected_response)):
            if corrected is None or printed is None:
                continue
            bad = frames.parse(printed, ex.mode)
            good = frames.parse(corrected, ex.mode)
            assert good.check_ok and frames.structure_problem(good, part) is None
            problem = frames.structure_problem(bad, part) if bad.check_ok else "checksum"
            assert problem is not None, f"printed {part} is in fact correct"
            if part == "response" and problem == "checksum":
                # the client refuses the printed reply: it is never decoded into values
                exchange = run_with_reply(model, ex, wire(printed, ex.mode))
                assert isinstance(exchange.error, TransportError), f"printed reply accepted: {exchange.result!r}"
    if ex.status == "illegible":
        assert ex.illegible, "an illegible example says what is lost"
        skipped.append(f"illegible: {ex.illegible}")
    SEEN[f"{model.name}/{ex.name}"] = ex.status
    if skipped:
        print(f"{case_id(model, ex)}: skipped steps: {'; '.join(skipped)}")


def test_lrc_worked_examples() -> None:
    """Every worked LRC example printed in a manual (edx §2.1) computes as printed."""
    from pymodbus.framer import FramerAscii

    seen = 0
    for model in MODELS.values():
        ck = model.protocol.checksum
        if ck is None or ck.lrc_example is None:
            continue
        lrc = ck.lrc_example
        assert FramerAscii.compute_LRC(lrc.data) == lrc.lrc
        if lrc.ascii:
            assert lrc.ascii.replace("'", "").replace(" ", "").upper() in (f"{lrc.lrc:02X}", f"{lrc.lrc:02X}".lower())
        seen += 1
    assert seen >= 1, "the edx manual's LRC worked example is in its map"


@pytest.mark.parametrize("model", list(MODELS.values()), ids=list(MODELS))
def test_crc_byte_order_as_printed(model: Model) -> None:
    """The first CRC byte on the wire is the CRC's low byte, whatever label the manual prints over it."""
    checked = 0
    for ex in model.examples:
        if ex.mode != "rtu":
            continue
        for text in (ex.wire_request, ex.wire_response):
            if text is None or not legible(text, "rtu"):
                continue
            data = bytes.fromhex(text)
            crc = 0xFFFF
            for byte in data[:-2]:
                crc ^= byte
                for _ in range(8):
                    crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
            assert data[-2] == crc & 0xFF and data[-1] == crc >> 8
            checked += 1
    if any(ex.mode == "rtu" for ex in model.examples):
        assert checked and model.protocol.checksum is not None


def _all_example_ids() -> Iterator[str]:
    for path in [*map_paths(), *TEST_MAPS]:
        model = compile_map(path)
        for ex in model.examples:
            yield f"{model.name}/{ex.name}"


def test_zz_every_example_was_run() -> None:
    """A map that gains an example the suite did not run fails here (runs last in this module)."""
    if not SEEN:
        pytest.fail("the round-trip tests did not run in this session (run the whole module)")
    missing = sorted(set(_all_example_ids()) - set(SEEN))
    assert not missing, f"examples not run: {missing}"


def test_zz_examples_command_agrees_with_the_run(capsys: pytest.CaptureFixture[str]) -> None:
    from drivemap.cli import main

    if not SEEN:
        pytest.fail("the round-trip tests did not run in this session (run the whole module)")
    assert main(["examples"]) == 0
    out = capsys.readouterr().out
    for model in PROJECT.values():
        statuses = [s for key, s in SEEN.items() if key.startswith(model.name + "/")]
        line = (f"{model.name}: frames {len(statuses)}, verified {statuses.count('verified')}, "
                f"errata {statuses.count('erratum')}, illegible {statuses.count('illegible')}")
        assert line in out.splitlines()

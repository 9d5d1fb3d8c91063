"""vfd1000's 03H reply as the manual prints it: a two-byte byte count, accepted by the client.

002 §Example read 03H prints the reply 01 03 00 04 00 00 00 00 43 07 (byte count 00H 04H, CRC right
for those bytes). The map keeps the standard reading (erratum) but lists the quirk
``two_byte_byte_count``: the client accepts a device answering exactly as printed. Proved with the
simulator started with the quirk, over a virtual serial line (the exact bytes on the wire) and TCP.
"""

from __future__ import annotations

import dataclasses
import importlib
from typing import Any

import pytest

from drivemap.runtime.errors import DriveTimeout
from drivemap.runtime.sim.simulator import SimulatorError
from tests.helpers_client import TIMEOUT, package, serial_server, tcp_server

vfd = package("vfd1000")
PRINTED_REQUEST = bytes.fromhex("01 03 00 04 00 02 85 CA")
PRINTED_RESPONSE = bytes.fromhex("01 03 00 04 00 00 00 00 43 07")
STANDARD_RESPONSE = bytes.fromhex("01 03 04 00 00 00 00 FA 33")
BAUD = 19200
VfdSimulator = importlib.import_module("drivemap_models.vfd1000.simulator").Simulator


def _sim(*quirks: str) -> Any:
    sim = VfdSimulator(reply_quirks=list(quirks))
    sim.set("parameter_0004", 0)
    sim.set("parameter_0005", 0)
    return sim


def _serial_client(line: Any, cls: Any = None) -> Any:
    cls = cls or vfd.Client
    return cls.serial(line.master_port, unit=1, baudrate=BAUD, parity="none", stopbits=1, timeout=TIMEOUT, retries=0)


def test_the_map_lists_the_quirk() -> None:
    assert vfd.SPEC.protocol.quirks == ("two_byte_byte_count",)
    assert all(not package(m).SPEC.protocol.quirks for m in ("edx", "ev", "v2"))


def test_client_accepts_the_printed_reply_on_a_serial_line() -> None:
    with serial_server("vfd1000", "rtu", baudrate=BAUD, sim=_sim("two_byte_byte_count")) as (_sim_, line):
        with _serial_client(line) as drive:
            snap = drive.read(drive.parameter_0004, drive.parameter_0005)
            assert (snap.parameter_0004, snap.parameter_0005) == (0, 0)
            line.wait_idle(1.0)
            assert line.captured("to_device") == PRINTED_REQUEST
            assert line.captured("to_master") == PRINTED_RESPONSE  # exactly as the manual prints it
            assert drive.stats.rejected == 0 and drive.stats.retries == 0


def test_client_decodes_values_in_both_forms_over_tcp() -> None:
    for quirks in ((), ("two_byte_byte_count",)):
        sim = _sim(*quirks)
        sim.set("parameter_0004", 0x1234)
        sim.set("parameter_0005", 5000)
        with tcp_server("vfd1000", sim=sim) as (_, host, port):
            with vfd.Client.tcp(host, port, timeout=TIMEOUT, retries=0) as drive:
                snap = drive.read(drive.parameter_0004, drive.parameter_0005)
                assert (snap.parameter_0004, snap.parameter_0005) == (0x1234, 5000), quirks
                assert drive.parameter_0005.read() == 5000


def test_standard_reply_still_accepted_on_a_serial_line() -> None:
    with serial_server("vfd1000", "rtu", baudrate=BAUD, sim=_sim()) as (_sim_, line):
        with _serial_client(line) as drive:
            assert drive.read(drive.parameter_0004, drive.parameter_0005).parameter_0005 == 0
            line.wait_idle(1.0)
            assert line.captured("to_master") == STANDARD_RESPONSE


def test_without_the_quirk_the_printed_reply_is_refused() -> None:
    """The acceptance comes from the map: the same client without reply_quirks cannot frame the reply."""

    class Plain(vfd.Client):  # type: ignore[misc, name-defined]
        SPEC = dataclasses.replace(vfd.SPEC, protocol=dataclasses.replace(vfd.SPEC.protocol, reply_quirks=()))

    with serial_server("vfd1000", "rtu", baudrate=BAUD, sim=_sim("two_byte_byte_count")) as (_sim_, line):
        with _serial_client(line, Plain) as drive:
            with pytest.raises(DriveTimeout):
                drive.read(drive.parameter_0004, drive.parameter_0005)


def test_simulator_refuses_a_quirk_the_map_does_not_list() -> None:
    with pytest.raises(SimulatorError, match="lists no reply quirk 'two_byte_byte_count'"):
        importlib.import_module("drivemap_models.ev.simulator").Simulator(reply_quirks=["two_byte_byte_count"])
    with pytest.raises(SimulatorError):
        VfdSimulator(reply_quirks=["no_such_quirk"])


def test_simulate_option_reaches_the_simulator() -> None:
    import argparse

    from drivemap.runtime.sim import cli as simcli

    parser = argparse.ArgumentParser()
    simcli.add_arguments(parser, with_model=True)
    args = parser.parse_args(["vfd1000", "--tcp", "127.0.0.1:0", "--reply-quirk", "two_byte_byte_count"])
    assert args.reply_quirks == ["two_byte_byte_count"]
    assert VfdSimulator(reply_quirks=args.reply_quirks).handle(1, bytes.fromhex("03 00 04 00 02")) == bytes.fromhex(
        "03 00 04 00 00 00 00")

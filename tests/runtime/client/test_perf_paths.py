"""The fast paths behave exactly as the general ones they shortcut: the sync serial receiver, snapshots
built without a per-field ``__init__``, bit-field records built by ``@record``."""

from __future__ import annotations

import dataclasses
from typing import Any

import pytest
from pymodbus.pdu.bit_message import ReadCoilsRequest, WriteSingleCoilRequest
from pymodbus.pdu.register_message import (
    ReadHoldingRegistersRequest,
    ReadInputRegistersRequest,
    WriteMultipleRegistersRequest,
    WriteSingleRegisterRequest,
)

from drivemap.runtime.client.transport.serialrx import SerialReceiver, reply_length
from drivemap.runtime.client.values.records import record
from drivemap.runtime.errors import DeviceException
from drivemap.testing.vserial import FrameFault
from tests.helpers_client import TIMEOUT, package, serial_server
from tests.runtime.client.test_client_faults import ascii_frame, rtu

ev = package("ev")


def test_reply_length_of_each_function() -> None:
    assert reply_length(ReadHoldingRegistersRequest(address=0, count=16)) == 5 + 32
    assert reply_length(ReadInputRegistersRequest(address=0, count=1)) == 7
    assert reply_length(ReadCoilsRequest(address=0, count=9)) == 5 + 2
    assert reply_length(WriteSingleRegisterRequest(address=0, registers=[1])) == 8
    assert reply_length(WriteMultipleRegistersRequest(address=0, registers=[1, 2])) == 8
    assert reply_length(WriteSingleCoilRequest(address=0, bits=[True])) == 8


@pytest.mark.parametrize("mode", [m for m in ("rtu", "ascii") if m in ev.SPEC.protocol.modes])
def test_sync_serial_bus_reads_replies_through_the_receiver(mode: str) -> None:
    exception = {"rtu": rtu("01 83 02"), "ascii": ascii_frame("01 83 02")}[mode]
    with serial_server("ev", mode) as (sim, line):
        sim.set("motor_speed", 321)
        with ev.Client.serial(line.master_port, unit=1, mode=mode, baudrate=38400, parity="none", stopbits=1,
                              timeout=TIMEOUT) as drive:
            receiver = drive.bus._receiver  # the stale-reply guard wraps client.recv around it
            assert isinstance(receiver, SerialReceiver)
            assert receiver.last_byte_at == 0.0
            assert drive.motor_speed.read() == 321
            assert receiver.last_byte_at > 0.0  # the reply came through the receiver, not pymodbus's poll
            sim.set("motor_speed", 654)
            assert drive.read(drive.motor_speed, drive.alarm_no).motor_speed == 654
            # an exception reply is shorter than the reply expected: its head says so, it is typed at once
            line.faults.add("to_master", FrameFault(drop=True, prefix=exception))
            with pytest.raises(DeviceException) as err:
                drive.motor_speed.read()
            assert err.value.code == 2 and drive.stats.retries == 0


def test_snapshot_without_generated_init_is_the_same_dataclass() -> None:
    snap_cls: Any = ev.Snapshot
    assert "__init__" not in snap_cls.__dict__  # SnapshotBase's, not one parameter per register
    snap = snap_cls(motor_speed=5)
    assert snap.motor_speed == 5 and snap.alarm_no is None
    assert snap == snap_cls(motor_speed=5) and snap != snap_cls(motor_speed=6)
    assert hash(snap) == hash(snap_cls(motor_speed=5))
    assert repr(snap) == "Snapshot(motor_speed=5)"
    assert dataclasses.replace(snap, alarm_no=3).alarm_no == 3
    with pytest.raises(dataclasses.FrozenInstanceError):
        snap.motor_speed = 1
    with pytest.raises(TypeError, match="no_such_field"):
        snap_cls(no_such_field=1)


def test_record_is_a_frozen_dataclass() -> None:
    @record
    class Status:
        run: bool
        mode: int

    @dataclasses.dataclass(frozen=True)
    class Reference:
        run: bool
        mode: int

    s = Status(True, mode=2)
    r = Reference(True, mode=2)
    assert repr(s) == repr(r).replace("Reference", "Status")
    assert s == Status(True, 2) and s != Status(False, 2) and s != r
    assert hash(s) == hash(r)
    assert dataclasses.is_dataclass(s) and dataclasses.asdict(s) == dataclasses.asdict(r)
    assert dataclasses.replace(s, mode=1) == Status(True, 1)
    assert Status.__match_args__ == ("run", "mode")
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.run = False  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        del s.run  # type: ignore[misc]
    for args, kwargs in (((), {}), ((True,), {}), ((True, 1, 2), {}), ((True,), {"run": False, "mode": 1}),
                         ((), {"run": True, "mode": 1, "other": 0})):
        with pytest.raises(TypeError):
            Status(*args, **kwargs)

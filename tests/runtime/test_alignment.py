"""Alignment rules (``protocol.alignment``): the simulator answers what the map says, the client
refuses raw reads, plans and writes that break them before the wire, the planner keeps them.

sdm630 (V1.8 §1.1, §3.11.1): even start addresses and quantities, whole floats, 02h otherwise; its
two-register reset is written whole.
"""

from __future__ import annotations

import struct
from dataclasses import replace

import pytest

from drivemap.runtime.alignment import aligned_limit, violation
from drivemap.runtime.client.protocol.planner import plan_reads
from drivemap.runtime.errors import MisalignedRequest
from drivemap.runtime.spec import AlignmentSpec
from tests.helpers_client import package, simulator, tcp_server


@pytest.mark.parametrize(("pdu", "answer"), [
    ("0400010002", "8402"),      # starts inside phase_1_voltage (issue: answered with data before)
    ("0400000003", "8402"),      # covers half of phase_2_voltage
    ("0400000001", "8402"),      # one register: not an even quantity
    ("0300020001", "8302"),      # half of demand_period
    ("10F010000102 0000", "9002"),  # a one-register write to the two-register reset
    ("1000030002 04 42700000", "9002"),  # a write starting inside demand_period
])
def test_simulator_refuses_what_the_map_says(pdu: str, answer: str) -> None:
    sim = simulator("sdm630")
    assert sim.handle(1, bytes.fromhex(pdu.replace(" ", ""))) == bytes.fromhex(answer)


def test_simulator_serves_aligned_requests() -> None:
    sim = simulator("sdm630")
    sim.set("phase_1_voltage", 230.5)
    assert sim.handle(1, bytes.fromhex("0400000002")) == b"\x04\x04" + struct.pack(">f", 230.5)
    assert sim.handle(1, bytes.fromhex("10F010000204 0000 0000".replace(" ", ""))) == bytes.fromhex("10F0100002")


def test_an_exception_code_of_the_rule_is_answered() -> None:
    sim = simulator("sdm630")
    rules = tuple(replace(r, exception=0x03) for r in sim.spec.protocol.alignment)
    sim.spec = replace(sim.spec, protocol=replace(sim.spec.protocol, alignment=rules))
    assert sim.handle(1, bytes.fromhex("0400010002")) == b"\x84\x03"


@pytest.mark.parametrize(("args", "why"), [
    (("input", 1, 2), "start address must be a multiple of 2"),
    (("input", 0, 1), "quantity must be a multiple of 2"),
    (("input", 0, 3), "quantity must be a multiple of 2"),
    (("holding", 2, 1), "quantity must be a multiple of 2"),
])
def test_client_refuses_misaligned_raw_reads_before_the_wire(args: tuple[str, int, int], why: str) -> None:
    with tcp_server("sdm630") as (_sim, host, port):
        with package("sdm630").Client.tcp(host, port, 1, timeout=2.0) as client:
            with pytest.raises(MisalignedRequest, match=why):
                client.read_registers(*args)
            assert client.stats.transactions == 0
            assert len(client.read_registers("input", 0, 4)) == 4  # aligned: read


def test_whole_values_names_the_register_cut() -> None:
    spec = package("sdm630").SPEC
    rule = replace(spec.protocol.alignment[0], start_multiple=1, quantity_multiple=1)
    loose = replace(spec, protocol=replace(spec.protocol, alignment=(rule,)))
    broken = violation(loose, "input", 1, 2, "read")
    assert broken is not None and "starts inside phase_1_voltage (0x0000..0x0001)" in broken[1]
    broken = violation(loose, "input", 0, 3, "read")
    assert broken is not None and "ends inside phase_2_voltage" in broken[1]
    assert violation(loose, "input", 0, 4, "read") is None
    assert violation(loose, "input", 1, 2, "write") is None  # the input rule covers reads only


def test_reset_is_written_whole_and_misaligned_writes_are_refused() -> None:
    with tcp_server("sdm630") as (_sim, host, port):
        with package("sdm630").Client.tcp(host, port, 1, timeout=2.0) as client:
            client.reset.execute()
            assert client.stats.by_function.get(0x10) == 1
            core = client._drivemap.core
            with pytest.raises(MisalignedRequest, match="write holding 0xF010 x1"):
                core._write_request("holding", 0xF010, [0])
            assert client.stats.transactions == 1


def test_the_plan_of_every_sdm630_register_keeps_the_rules() -> None:
    spec = package("sdm630").SPEC
    keys = [(r.name, i) for r in spec.registers if r.readable for i in range(r.count)]
    plan = plan_reads(spec, keys)
    assert plan
    for req in plan:
        assert req.address % 2 == 0 and req.count % 2 == 0, req
        assert violation(spec, req.table, req.address, req.count, "read") is None


def test_the_planner_rounds_its_limit_to_the_quantity_multiple() -> None:
    spec = package("sdm630").SPEC
    rule = AlignmentSpec("input", quantity_multiple=3, source="test")
    codes = tuple(replace(fc, max_quantity=80) for fc in spec.protocol.function_codes)
    odd = replace(spec, protocol=replace(spec.protocol, alignment=(rule,), function_codes=codes))
    assert aligned_limit(odd, "input", 80) == 78
    assert aligned_limit(odd, "holding", 80) == 80
    assert aligned_limit(spec, "input", 80) == 80

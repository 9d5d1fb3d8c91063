"""ev ``read_all()`` with the default page_policy "raise" (a read must leave the drive on the page it found).

ev's monitor addresses 0008h-000Fh show page 0 or 1 of the monitor data depending on 09-11
watch_data_select (001 §1.1, §4.3). ``read_all()`` visits each page it needs and puts the selector
back to the page it found, also when a read fails; ``read()`` of another page still raises WrongPage,
with a message that says how to read it.
"""

from __future__ import annotations

import importlib
from typing import Any

import pytest

from drivemap.runtime.errors import WrongPage
from tests.helpers_client import TIMEOUT, package, tcp_server

ev = package("ev")
EvSimulator = importlib.import_module("drivemap_models.ev.simulator").Simulator


def _sim(page: int) -> Any:
    sim = EvSimulator()
    sim.set("watch_data_select", page)
    sim.set("bus_voltage", 48.0)  # page 0
    sim.set("a1_voltage", 2.5)  # page 1
    return sim


def _check_snapshot(snap: Any) -> None:
    for reg in ev.SPEC.registers:
        if reg.readable:
            assert getattr(snap, reg.name) is not None, reg.name
    assert snap.bus_voltage == pytest.approx(48.0) and snap.a1_voltage == pytest.approx(2.5)


@pytest.mark.parametrize("page", [0, 1])
def test_read_all_visits_both_pages_and_restores_the_selector(page: int) -> None:
    sim = _sim(page)
    with tcp_server("ev", sim=sim) as (_, host, port):
        with ev.Client.tcp(host, port, timeout=TIMEOUT) as drive:
            assert drive.page_policy == "raise"
            _check_snapshot(drive.read_all())
            assert sim.get("watch_data_select") == page
            # page 0 found: read it, switch to 1, then back to 0; page 1 found: switch to 0, then back to 1
            assert drive.stats.by_function.get(0x06, 0) == 2
            _check_snapshot(drive.read_all())  # again, from the known page
            assert sim.get("watch_data_select") == page


async def test_async_read_all_visits_and_restores() -> None:
    sim = _sim(0)
    with tcp_server("ev", sim=sim) as (_, host, port):
        async with ev.AsyncClient.tcp(host, port, timeout=TIMEOUT) as drive:
            _check_snapshot(await drive.read_all())
    assert sim.get("watch_data_select") == 0


class _FailingPage1(EvSimulator):  # type: ignore[misc, valid-type]
    """Answers 04h once to the first read of 0008h-000Fh while page 1 is selected."""

    failed = False

    def handle(self, unit_id: int, pdu: bytes, **options: bool) -> bytes | None:
        address = int.from_bytes(pdu[1:3], "big") if len(pdu) >= 3 else -1
        if (pdu[:1] == b"\x03" and 0x0008 <= address <= 0x000F and self.get_raw("watch_data_select") == 1
                and not self.failed):
            self.failed = True
            return bytes([0x83, 0x04])
        return super().handle(unit_id, pdu, **options)


def test_selector_restored_after_a_failed_read() -> None:
    sim = _FailingPage1()
    sim.set("bus_voltage", 48.0)
    sim.set("a1_voltage", 2.5)
    with tcp_server("ev", sim=sim) as (_, host, port):
        with ev.Client.tcp(host, port, timeout=TIMEOUT) as drive:
            with pytest.raises(ev.EXCEPTIONS[0x04]):
                drive.read_all()
            assert sim.failed and sim.get("watch_data_select") == 0
            _check_snapshot(drive.read_all())


def test_read_of_another_page_still_raises_and_says_how() -> None:
    sim = _sim(0)
    with tcp_server("ev", sim=sim) as (_, host, port):
        with ev.Client.tcp(host, port, timeout=TIMEOUT) as drive:
            with pytest.raises(WrongPage, match=r"page_policy='switch', or read_all\(\)"):
                drive.read(drive.a1_voltage)
            assert drive.stats.by_function.get(0x06, 0) == 0  # nothing written by a refused read


def test_switch_policy_leaves_the_last_page() -> None:
    sim = _sim(0)
    with tcp_server("ev", sim=sim) as (_, host, port):
        with ev.Client.tcp(host, port, timeout=TIMEOUT, page_policy="switch") as drive:
            _check_snapshot(drive.read_all())
    assert sim.get("watch_data_select") == 1

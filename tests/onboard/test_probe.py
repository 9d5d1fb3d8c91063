"""`drivemap probe`: every readable block of every shipped simulator and nothing else, reads only,
the SunSpec walk of the Fronius simulator, snapshots and --diff, and bad input."""

from __future__ import annotations

import contextlib
import json
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from helpers_client import simulator, tcp_server
from helpers_live import ROOT, cli, no_traceback, simulate
from sim_helpers import free_port

from drivemap.compiler import compile_map
from drivemap.runtime.spec import DeviceSpec

MAPS = sorted(p.stem for p in (ROOT / "maps").glob("*.yaml"))
TABLES = ("holding", "input", "coil", "discrete")
SUNSPEC_IDS = {"common": 1, "inverter": 103, "nameplate": 120, "settings": 121, "status": 122, "controls": 123,
               "mppt": 160, "storage": 124}


def record(sim: Any, codes: list[int], requests: list[tuple[float, bytes]] | None = None) -> None:
    """Every request PDU the simulator receives: its function code (and when, and the PDU)."""
    handle = sim.handle

    def recording(unit: int, pdu: bytes, **kw: Any) -> Any:
        codes.append(pdu[0])
        if requests is not None:
            requests.append((time.monotonic(), pdu))
        return handle(unit, pdu, **kw)

    sim.handle = recording


@contextlib.contextmanager
def served(model: str, requests: list[tuple[float, bytes]] | None = None) -> Iterator[tuple[Any, str, list[int]]]:
    """The model's simulator on 127.0.0.1 (unit 1): (simulator, HOST:PORT, function codes it received)."""
    with tcp_server(model) as (sim, host, port):
        codes: list[int] = []
        record(sim, codes, requests)
        yield sim, f"{host}:{port}", codes


def readable_words(spec: DeviceSpec, values: dict[str, Any]) -> set[tuple[str, int]]:
    """What the map says reads on the current pages: every word of a readable register, and the
    reserved ranges marked readable (the expected result, from the map, not from the simulator)."""

    def on_page(page: Any) -> bool:
        return page is None or values.get(page.selector, 0) == page.value

    out: set[tuple[str, int]] = set()
    for reg in spec.registers:
        if reg.readable and on_page(reg.page):
            out |= {(reg.table, reg.element_address(i) + w) for i in range(reg.count) for w in range(reg.words)}
    for res in spec.reserved:
        if res.readable and on_page(res.page):
            out |= {(res.table, a) for a in range(res.start, res.end + 1)}
    return out


def ranges_of(words: set[tuple[str, int]], margin: int = 24) -> str:
    """Address ranges around the map's words (clusters apart by more than 256 are swept apart)."""
    spans: list[list[int]] = []
    for a in sorted({a for _, a in words}):
        lo, hi = max(0, a - margin), min(0xFFFF, a + margin)
        if spans and lo <= spans[-1][1] + 256:
            spans[-1][1] = max(spans[-1][1], hi)
        else:
            spans.append([lo, hi])
    return ",".join(f"{lo}-{hi}" for lo, hi in spans)


def snapshot_words(path: Path) -> set[tuple[str, int]]:
    doc = json.loads(path.read_text(encoding="utf-8"))
    return {(t, int(a)) for t, cells in doc["tables"].items() for a in cells}


@pytest.mark.parametrize("model", MAPS)
def test_probe_finds_every_readable_block_and_nothing_else(model: str, tmp_path: Path) -> None:
    with served(model) as (sim, where, codes):
        expected = readable_words(sim.spec, sim.unit(1).values)
        out = tmp_path / "maps" / f"{model}_probed.yaml"
        proc = cli("probe", "--tcp", where, "--unit", "1", "--tables", ",".join(TABLES), "--range",
                   ranges_of(expected), "--rate", "100000", "--snapshot", str(tmp_path / "s.json"), "-o", str(out),
                   timeout=300)
    no_traceback(proc)
    assert proc.returncode == 0, proc.stderr
    assert snapshot_words(tmp_path / "s.json") == expected
    assert set(codes) <= {1, 2, 3, 4} and codes  # reads only: no write function code reached the simulator
    probed = compile_map(out)  # the skeleton validates as written
    cells = {(r.table, r.address + i) for r in probed.registers for i in range(r.count)}
    assert cells == expected
    assert all(r.source.startswith("probe 20") and r.type in ("u16", "bool") for r in probed.registers)
    # a device with alignment rules refuses single-word reads: the words it answers in pairs are said so
    assert ("input: reads at even addresses in even quantities only" in proc.stdout) == any(
        a.start_multiple == 2 for a in sim.spec.protocol.alignment), proc.stdout
    # what the budget left open is listed as unresolved, and only then
    assert ("unresolved (" in proc.stdout) == ("stopped by the read budget" in proc.stdout), proc.stdout


def fronius_values(registers: Any) -> dict[str, int]:
    """The SunSpec values a Fronius Symo Hybrid presents (printed in its documents, quoted in the map's
    notes), which the map gives no defaults for: "SunS", each model's ID and L, the end model."""
    address = {r.name: r.address for r in registers}
    order = sorted(SUNSPEC_IDS, key=lambda g: address[f"{g}_model_id"])
    values = {"sunspec_id": 0x53756E53, "end_block_id": 0xFFFF, "end_block_length": 0}
    for i, group in enumerate(order):
        after = address[f"{order[i + 1]}_model_id"] if i + 1 < len(order) else address["end_block_id"]
        values[f"{group}_model_id"] = SUNSPEC_IDS[group]
        values[f"{group}_model_length"] = after - address[f"{group}_model_id"] - 2
    return values


def fronius_chain(sim: Any) -> None:
    for name, raw in fronius_values(sim.spec.registers).items():
        sim.set_raw(name, raw)


def cell_types(model: Any, first: int) -> dict[int, tuple[str, int, int | None]]:
    """address of each element at or above ``first`` -> (type, words, address of its scale register)."""
    out = {}
    for reg in model.registers:
        scale = model.register(reg.scale_register).address if reg.scale_register else None
        for i in range(reg.count):
            if reg.element_address(i) >= first:
                out[reg.element_address(i)] = (reg.type, reg.words, scale)
    return out


def test_probe_sunspec_walk_recovers_the_fronius_models(tmp_path: Path) -> None:
    import sunspec2  # noqa: F401  (the sunspec extra is a test dependency: pip install -e '.[test]')
    with served("fronius_symo_hybrid") as (sim, where, codes):
        fronius_chain(sim)
        out = tmp_path / "fronius_probed.yaml"
        proc = cli("probe", "--tcp", where, "--sunspec", "--rate", "100000", "-o", str(out))
    assert proc.returncode == 0, proc.stderr
    assert set(codes) <= {3}
    assert ("models 1 (L 65) at 40002, 103 (L 50) at 40069, 120 (L 26) at 40121, 121 (L 30) at 40149, "
            "122 (L 44) at 40181, 123 (L 24) at 40227, 160 (L 48) at 40253, 124 (L 24) at 40303") in proc.stdout
    proven = cell_types(compile_map(ROOT / "maps" / "fronius_symo_hybrid.yaml"), 40000)
    recovered = cell_types(compile_map(out), 40000)
    same = [a for a in proven if recovered.get(a) == proven[a]]
    print(f"SunSpec probe of the Fronius simulator: {len(same)}/{len(proven)} register cells of the proven map "
          f"recovered with address, type, words and scale register; {len(set(recovered) - set(proven))} extra")
    assert set(recovered) == set(proven)  # every proven cell, nothing else
    assert len(same) >= len(proven) - 2, sorted(set(proven) - set(same))


def test_probe_sunspec_without_the_extra_writes_raw_models(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    from drivemap.cli import main
    from drivemap.onboard.importers import sunspec

    monkeypatch.setattr(sunspec, "models_dir", lambda: None)
    monkeypatch.setattr("drivemap.onboard.probe_map.models_dir", lambda: None)
    with served("fronius_symo_hybrid") as (sim, where, _):
        fronius_chain(sim)
        code = main(["probe", "--tcp", where, "--sunspec", "--rate", "100000", "-o", str(tmp_path / "raw.yaml")])
    assert code == 0, capsys.readouterr().err
    model = compile_map(tmp_path / "raw.yaml")
    assert model.register("model_160_length").address == 40254
    assert model.register("model_160_words_0").count == 48
    assert "drivemap[sunspec]" in capsys.readouterr().out


def test_probe_snapshots_and_diff(tmp_path: Path) -> None:
    with served("sdm630") as (sim, where, _):
        args = ("probe", "--tcp", where, "--tables", "input", "--range", "0-20", "--rate", "100000", "--force",
                "-o", str(tmp_path / "m.yaml"))
        first = cli(*args, "--snapshot", str(tmp_path / "a.json"))
        sim.set("phase_2_voltage", 231.5)
        second = cli(*args, "--snapshot", str(tmp_path / "b.json"))
    assert first.returncode == 0 and second.returncode == 0, first.stderr + second.stderr
    diff = cli("probe", "--diff", str(tmp_path / "a.json"), str(tmp_path / "b.json"))
    assert diff.returncode == 0, diff.stderr
    lines = diff.stdout.splitlines()
    assert lines[-1] == "2 registers changed" and lines[0].startswith("input 2 (0x0002): 0 (0x0000) -> 17255")
    assert lines[1].startswith("input 3 (0x0003): 0 (0x0000) -> ")
    bad = tmp_path / "bad.json"
    bad.write_text('{"drivemap_probe": 1,\n "tables": [}', encoding="utf-8")
    proc = cli("probe", "--diff", str(bad), str(tmp_path / "b.json"))
    assert proc.returncode == 1 and f"{bad}:2:" in proc.stderr and ": error: not JSON" in proc.stderr
    no_traceback(proc)


def test_probe_bad_input_is_located_and_sends_nothing(tmp_path: Path) -> None:
    existing = tmp_path / "probed_device.yaml"
    existing.write_text("mine\n", encoding="utf-8")
    with served("ev") as (_, where, codes):
        bad_range = cli("probe", "--tcp", where, "--range", "10-x", "-o", str(tmp_path / "x.yaml"))
        kept = cli("probe", "--tcp", where, "--range", "0-9", "-o", str(existing))
        snap = cli("probe", "--tcp", where, "--range", "0-9", "--snapshot", str(existing), "-o",
                   str(tmp_path / "new.yaml"))
        reversed_range = cli("probe", "--tcp", where, "--range", "9-3", "-o", str(tmp_path / "x.yaml"))
        assert codes == []  # refused before anything was sent
        started = time.monotonic()
        silent_unit = cli("probe", "--tcp", where, "--unit", "9", "--range", "0-9999", "--timeout", "0.2",
                          "-o", str(tmp_path / "y.yaml"))
        assert time.monotonic() - started < 30  # stops after 3 unanswered reads, not 10000 addresses later
    for proc in (bad_range, kept, silent_unit):
        no_traceback(proc)
    assert bad_range.returncode == 1 and bad_range.stderr.startswith("<command line>:1:")
    assert "error: --range wants A-B" in bad_range.stderr
    assert kept.returncode == 1 and "file exists; not overwritten (pass --force)" in kept.stderr
    assert snap.returncode == 1 and "file exists; not overwritten" in snap.stderr
    assert reversed_range.returncode == 1 and "--range 9-3: addresses are 0..65535 and A <= B" in reversed_range.stderr
    assert existing.read_text(encoding="utf-8") == "mine\n"
    assert silent_unit.returncode == 3 and "no answer from unit 9" in silent_unit.stderr
    assert "no answer to the first 3 reads" in silent_unit.stderr
    assert codes and set(codes) <= {3, 4}  # the silent unit got reads only
    assert sorted(p.name for p in tmp_path.iterdir()) == ["probed_device.yaml"]
    closed = cli("probe", "--tcp", f"127.0.0.1:{free_port()}", "-o", str(tmp_path / "z.yaml"))
    assert closed.returncode == 2 and closed.stderr.startswith("drivemap probe: error: cannot connect to 127.0.0.1:")
    assert not (tmp_path / "z.yaml").exists()


def test_probe_cli_in_an_empty_folder_writes_into_the_project_maps(tmp_path: Path) -> None:
    with served("vfd1000") as (_, where, _codes):
        proc = cli("probe", "--tcp", where, "--range", "0x2000-0x2010", "--rate", "100000", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    written = tmp_path / "maps" / "probed_device.yaml"
    assert sorted(p.relative_to(tmp_path).as_posix() for p in tmp_path.rglob("*")) == ["maps", "maps/probed_device.yaml"]
    validate = cli("validate", cwd=tmp_path)
    assert validate.returncode == 0 and "maps/probed_device.yaml: ok" in validate.stdout, validate.stderr
    assert compile_map(written).registers


def test_probe_keeps_to_the_rate_and_the_max_quantity(tmp_path: Path) -> None:
    requests: list[tuple[float, bytes]] = []
    with served("sdm630", requests) as (_, where, _codes):
        proc = cli("probe", "--tcp", where, "--tables", "input", "--range", "0-59", "--max-quantity", "8",
                   "--rate", "25", "-o", str(tmp_path / "m.yaml"))
    assert proc.returncode == 0, proc.stderr
    assert len(requests) >= 8
    assert all(pdu[0] == 0x04 and int.from_bytes(pdu[3:5], "big") <= 8 for _, pdu in requests)
    span = requests[-1][0] - requests[0][0]  # times seen by the server: each one may arrive a little late
    assert span >= 0.9 * (len(requests) - 1) / 25, (span, len(requests))  # at most 25 requests a second


def test_probe_over_a_serial_line(tmp_path: Path) -> None:
    from drivemap.runtime.sim.serve import ThreadedSimServer
    from drivemap.testing.vserial import VirtualSerialLine

    sim = simulator("ev", (2,))
    codes: list[int] = []
    record(sim, codes)
    with VirtualSerialLine(19200) as line:
        with ThreadedSimServer(sim, serial=line.device_port, mode="rtu", baudrate=19200, parity="none"):
            proc = cli("probe", "--serial", line.master_port, "--baudrate", "19200", "--parity", "none",
                       "--unit", "2", "--range", "0-15", "--rate", "1000", "-o", str(tmp_path / "ev_serial.yaml"))
    assert proc.returncode == 0, proc.stderr
    assert set(codes) <= {3, 4} and codes
    found = {(r.table, r.address + i) for r in compile_map(tmp_path / "ev_serial.yaml").registers for i in range(r.count)}
    assert found == {w for w in readable_words(sim.spec, sim.unit(2).values) if w[1] <= 15}


def test_probe_keeps_to_the_maps_max_quantity(tmp_path: Path) -> None:
    requests: list[tuple[float, bytes]] = []
    with served("v2", requests) as (_, where, _codes):  # v2 reads at most 16 words per request
        proc = cli("probe", "--tcp", where, "--map", "v2", "--tables", "holding", "--range", "0-99", "--rate",
                   "100000", "-o", str(tmp_path / "v2_probed.yaml"))
    assert proc.returncode == 0, proc.stderr
    assert max(int.from_bytes(pdu[3:5], "big") for _, pdu in requests) == 16


def test_probe_reads_by_the_maps_alignment_rules(tmp_path: Path) -> None:
    """sdm630's input registers take only even starts and quantities (whole floats): with --map the
    probe reads them so from the start (no single-word read is refused) and finds every float."""
    requests: list[tuple[float, bytes]] = []
    with served("sdm630", requests) as (sim, where, _codes):
        expected = {w for w in readable_words(sim.spec, sim.unit(1).values) if w[0] == "input" and w[1] <= 99}
        proc = cli("probe", "--tcp", where, "--map", "sdm630", "--tables", "input", "--range", "0-99", "--rate",
                   "100000", "--snapshot", str(tmp_path / "s.json"), "-o", str(tmp_path / "sdm630_probed.yaml"))
    no_traceback(proc)
    assert proc.returncode == 0, proc.stderr
    assert snapshot_words(tmp_path / "s.json") == expected
    reads = [(int.from_bytes(pdu[1:3], "big"), int.from_bytes(pdu[3:5], "big")) for _, pdu in requests if pdu[0] == 4]
    assert reads and all(start % 2 == 0 and count % 2 == 0 for start, count in reads), [r for r in reads if r[0] % 2 or r[1] % 2]
    assert "input: read in pairs at even addresses as the map's alignment rules ask" in proc.stdout, proc.stdout


def test_probe_stops_when_the_device_goes_away(tmp_path: Path) -> None:
    with served("ev") as (sim, where, codes):
        answering = sim.handle

        def leaves(unit: int, pdu: bytes, **kw: Any) -> Any:
            return answering(unit, pdu, **kw) if len(codes) <= 40 else None  # unplugged after 40 requests

        sim.handle = leaves
        proc = cli("probe", "--tcp", where, "--range", "0-9999", "--timeout", "0.1", "--rate", "100000",
                   "-o", str(tmp_path / "gone.yaml"))
    no_traceback(proc)
    assert proc.returncode == 3, proc.stderr
    assert "20 reads in a row went unanswered after" in proc.stderr
    assert not (tmp_path / "gone.yaml").exists()


def test_probe_sunspec_against_drivemap_simulate(tmp_path: Path) -> None:
    """The walk against ``drivemap simulate`` itself: a copy of the Fronius map whose SunSpec marker,
    model IDs and lengths carry their fixed values as defaults (the shipped map gives none)."""
    import re

    import sunspec2  # noqa: F401  (the sunspec extra is a test dependency)

    source = ROOT / "maps" / "fronius_symo_hybrid.yaml"
    text = source.read_text(encoding="utf-8").replace("../schemas/", f"{ROOT / 'schemas'}/")
    for name, value in fronius_values(compile_map(source).registers).items():
        entry = re.compile(rf"(  - name: {name}\n(?:    .*\n)*?)(    source:)")
        text, found = entry.subn(rf"\g<1>    default: {value}\n\g<2>", text, count=1)
        assert found == 1, name
    served_map = tmp_path / "sim" / "fronius_symo_hybrid.yaml"
    served_map.parent.mkdir()
    served_map.write_text(text, encoding="utf-8")
    with simulate(str(served_map)) as port:
        proc = cli("probe", "--tcp", f"127.0.0.1:{port}", "--sunspec", "--rate", "1000", "-o",
                   str(tmp_path / "fronius_probed.yaml"))
    assert proc.returncode == 0, proc.stderr
    assert "160 (L 48) at 40253, 124 (L 24) at 40303" in proc.stdout and "18 reads" in proc.stdout
    recovered = cell_types(compile_map(tmp_path / "fronius_probed.yaml"), 40000)
    assert set(recovered) == set(cell_types(compile_map(source), 40000))

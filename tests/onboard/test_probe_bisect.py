"""`drivemap probe` by bisection with a budget: the full address space of both word tables in a few
thousand reads, every readable word of the map found, reads only; unresolved ranges are listed, never
called empty; --exhaustive keeps the word-by-word proof; a device answering garbage stops the probe."""

from __future__ import annotations

import json
import socket
import threading
from pathlib import Path

import pytest
from helpers_client import tcp_server
from helpers_live import cli, no_traceback
from test_probe import ranges_of, readable_words, record, served, snapshot_words

from drivemap.compiler import compile_cached, compile_map
from drivemap.device.target import spec_of
from drivemap.frontend.project import catalogue_maps
from drivemap.runtime.package import load_package


@pytest.mark.parametrize("model", ["sdm630", "fronius_symo_hybrid"])
def test_full_address_space_in_three_reads_per_block(model: str, tmp_path: Path) -> None:
    with served(model) as (sim, where, codes):
        expected = {w for w in readable_words(sim.spec, sim.unit(1).values) if w[0] in ("holding", "input")}
        proc = cli("probe", "--tcp", where, "--range", "0-65535", "--rate", "1000000", "--snapshot",
                   str(tmp_path / "s.json"), "-o", str(tmp_path / "m.yaml"), timeout=300, cwd=tmp_path)
    no_traceback(proc)
    assert proc.returncode == 0, proc.stderr
    assert set(codes) <= {3, 4} and 1050 <= len(codes) <= 3150  # frame level: reads only, within the budget
    assert snapshot_words(tmp_path / "s.json") == expected
    doc = json.loads((tmp_path / "s.json").read_text(encoding="utf-8"))
    assert doc["unresolved"]["holding"]  # the budget ran out: what was not proven is listed, not empty
    assert "stopped by the read budget" in proc.stdout and "unresolved (" in proc.stdout
    assert f"every register of the shipped map {model} in these ranges answered" in proc.stdout  # an empty folder
    seconds = int(proc.stdout.split("reads take ~")[1].split(" s")[0])
    assert seconds <= 300  # the frames at 19200 Bd
    text = (tmp_path / "m.yaml").read_text(encoding="utf-8")
    assert "evidence: probed" in text
    model_ = compile_map(tmp_path / "m.yaml")
    assert all(r.review and "type" in r.review and "scale" in r.review for r in model_.registers)


def test_probe_suggests_the_catalogue_map_of_the_device_it_found(tmp_path: Path) -> None:
    """A device only the catalogue knows (a drive imported from modbus_local_gateway), probed in a folder
    without maps: the maps weighed are the shipped ones and the catalogue, and the catalogue map whose
    every register answered is named, to verify."""
    path = next(p for p in catalogue_maps() if p.stem == "schneider_atv312")
    spec = spec_of(compile_cached(path))
    sim = load_package(spec).simulator.Simulator(units=[1])
    codes: list[int] = []
    record(sim, codes)
    words = {w for w in readable_words(spec, sim.unit(1).values) if w[0] in ("holding", "input")}
    with tcp_server(spec.name, sim=sim) as (_, host, port):
        proc = cli("probe", "--tcp", f"{host}:{port}", "--range", ranges_of(words), "--rate", "1000000",
                   "--exhaustive", "-o", str(tmp_path / "m.yaml"), timeout=300, cwd=tmp_path)
    no_traceback(proc)
    assert proc.returncode == 0, proc.stderr
    assert set(codes) <= {3, 4}
    named = [line for line in proc.stdout.splitlines() if "in these ranges answered" in line]
    assert any("the catalogue map schneider_atv312 " in line for line in named), proc.stdout
    assert not any("the project's map" in line for line in named)  # an empty folder has no project maps


def test_without_hints_a_budget_leaves_ranges_unresolved_not_empty(tmp_path: Path) -> None:
    with served("ev") as (sim, where, codes):
        proc = cli("probe", "--tcp", where, "--range", "0-4999", "--no-hints", "--budget", "60", "--rate", "1000000",
                   "--snapshot", str(tmp_path / "s.json"), "-o", str(tmp_path / "m.yaml"))
    assert proc.returncode == 0, proc.stderr
    assert len(codes) == 60
    doc = json.loads((tmp_path / "s.json").read_text(encoding="utf-8"))
    left = {t: [tuple(map(int, s.split("-"))) for s in spans] for t, spans in doc["unresolved"].items()}
    read = {(t, int(a)) for t, cells in doc["tables"].items() for a in cells}
    unreadable = {(t, a) for t, spans in doc.get("unreadable", {}).items() for s in spans
                  for a in range(int(s.split("-")[0]), int(s.split("-")[1]) + 1)}
    unknown = {(t, a) for t, spans in left.items() for lo, hi in spans for a in range(lo, hi + 1)}
    # every address is exactly one of: read, proven unreadable, unresolved
    assert not (read & unreadable) and not (read & unknown) and not (unreadable & unknown)
    assert len(read) + len(unreadable) + len(unknown) == 2 * 5000
    assert "stopped by the read budget" in proc.stdout


def test_exhaustive_keeps_the_word_by_word_proof(tmp_path: Path) -> None:
    with served("ev") as (sim, where, codes):
        expected = {w for w in readable_words(sim.spec, sim.unit(1).values) if w[0] in ("holding", "input")
                    and w[1] <= 299}
        proc = cli("probe", "--tcp", where, "--range", "0-299", "--exhaustive", "--rate", "1000000", "--snapshot",
                   str(tmp_path / "s.json"), "-o", str(tmp_path / "m.yaml"))
    assert proc.returncode == 0, proc.stderr
    assert snapshot_words(tmp_path / "s.json") == expected
    assert "unresolved" not in proc.stdout
    bad = cli("probe", "--tcp", where, "--exhaustive", "--budget", "10", "-o", str(tmp_path / "x.yaml"))
    assert bad.returncode == 1 and "--exhaustive proves every word: it takes no --budget" in bad.stderr


class _GarbageAfterFirst:
    """A Modbus TCP device that answers the first read right, then with replies to another function."""

    def __init__(self) -> None:
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen()
        self.port = int(self.sock.getsockname()[1])
        self.requests = 0
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self) -> None:
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            with conn:
                while (head := conn.recv(7)) and len(head) == 7:
                    pdu = conn.recv(int.from_bytes(head[4:6], "big") - 1)
                    self.requests += 1
                    count = int.from_bytes(pdu[3:5], "big")
                    code = pdu[0] if self.requests == 1 else 0x11
                    body = bytes([code, 2 * count]) + b"\x00\x01" * count
                    conn.sendall(head[:4] + (len(body) + 1).to_bytes(2, "big") + head[6:7] + body)

    def close(self) -> None:
        self.sock.close()


def test_a_device_answering_garbage_stops_the_probe_as_read_does(tmp_path: Path) -> None:
    device = _GarbageAfterFirst()
    try:
        proc = cli("probe", "--tcp", f"127.0.0.1:{device.port}", "--range", "0-65535", "--timeout", "0.2",
                   "--rate", "1000000", "-o", str(tmp_path / "m.yaml"), timeout=60)
    finally:
        device.close()
    no_traceback(proc)
    assert proc.returncode == 4, (proc.returncode, proc.stderr)
    assert proc.stderr.startswith("drivemap probe: error: unit 1 on tcp 127.0.0.1:")
    assert "answered, but not what was asked (reply has function 0x11, sent 0x03)" in proc.stderr
    assert "no answer" not in proc.stderr
    assert device.requests <= 10
    assert not (tmp_path / "m.yaml").exists()


@pytest.mark.parametrize(("args", "said"), [
    (["--rate", "1e-300"], "--rate: requests per second"),
    (["--rate", "nan"], "--rate: requests per second"),
    (["--unit", "256"], "--unit: a unit id 1..255"),
    (["--budget", "0"], "--budget: a number of reads"),
    (["--time", "-1"], "--time: seconds"),
])
def test_bad_numbers_are_located_and_send_nothing(args: list[str], said: str, tmp_path: Path) -> None:
    with served("ev") as (_, where, codes):
        proc = cli("probe", "--tcp", where, *args, "-o", str(tmp_path / "m.yaml"))
    no_traceback(proc)
    assert proc.returncode == 1 and proc.stderr.startswith("<command line>:1:") and said in proc.stderr, proc.stderr
    assert codes == []


def test_diff_refuses_what_is_not_a_snapshot_file(tmp_path: Path) -> None:
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 100_000 + "]" * 100_000, encoding="utf-8")
    for path, said in ((deep, "JSON nested too deeply"), (Path("/dev/zero"), "not a regular file"),
                       (tmp_path, "not a regular file")):
        proc = cli("probe", "--diff", str(path), str(path), timeout=30)
        no_traceback(proc)
        assert proc.returncode == 1 and said in proc.stderr, proc.stderr

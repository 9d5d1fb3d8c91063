"""Issue 34: a multi-word register whose source states its type but not the order of its words keeps the
type, with ``review: [word_order]`` in place of ``word_order`` (a draft used to drop the stated ``u32`` or
``float`` to satisfy the compiler). ``validate`` accepts it and counts the item, a register with neither
is refused at its line, the generated client reads it high word first and warns, refuses to write it and
sends nothing, the Markdown docs say the order is open and ESPHome gets the wire bytes undecoded.
Against the generated package of sdm630 with two registers' word order taken out, and its simulator on
127.0.0.1."""

from __future__ import annotations

import importlib
import sys
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

from drivemap.build import render_tree, write_tree
from drivemap.compiler import compile_map
from drivemap.runtime.errors import OpenForReview, ReviewWarning
from drivemap.runtime.sim.serve import ThreadedSimServer
from tests.helpers_live import run

ROOT = Path(__file__).resolve().parents[3]
OPEN = ("demand_period", "phase_1_voltage")  # rw f32, r f32


def _text(review: bool) -> str:
    text = (ROOT / "maps" / "sdm630.yaml").read_text(encoding="utf-8")
    for name in OPEN:
        head = f"\n  - name: {name}\n"
        start = text.index(head) + len(head)
        end = text.index("\n  - name: ", start)
        block = text[start:end]
        assert block.count("    word_order: high_first\n") == 1
        block = block.replace("    word_order: high_first\n", "    review: [word_order]\n" if review else "")
        text = text[:start] + block + text[end:]
    return text.replace("../schemas/", str(ROOT / "schemas") + "/")


@pytest.fixture(scope="module")
def generated(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Path, ModuleType]]:
    folder = tmp_path_factory.mktemp("wordorder")
    path = folder / "sdm630.yaml"
    path.write_text(_text(review=True), encoding="utf-8")
    write_tree(folder / "out" / "wopkg", render_tree([compile_map(path)]), force=True)
    sys.path.insert(0, str(folder / "out"))
    try:
        yield path, importlib.import_module("wopkg.sdm630")
    finally:
        sys.path.remove(str(folder / "out"))
        for name in [n for n in sys.modules if n == "wopkg" or n.startswith("wopkg.")]:
            del sys.modules[name]


def test_validate_counts_it_and_refuses_neither(tmp_path: Path, generated: tuple[Path, ModuleType]) -> None:
    path, _ = generated
    proc = run("validate", str(path))
    assert proc.returncode == 0, proc.stderr
    assert "2 open" in proc.stdout + proc.stderr, proc.stdout + proc.stderr
    bare = tmp_path / "sdm630.yaml"
    bare.write_text(_text(review=False), encoding="utf-8")
    proc = run("validate", str(bare))
    assert proc.returncode == 1
    errors = [line for line in proc.stderr.splitlines() if ": error: " in line]
    assert len(errors) == 2 and all(line.startswith(f"{bare}:") for line in errors), proc.stderr
    assert "f32 register needs word_order (high_first or low_first), or review: [word_order]" in errors[0]
    assert "Traceback" not in proc.stderr


def test_client_reads_high_first_warns_and_refuses_writes(generated: tuple[Path, ModuleType]) -> None:
    _, pkg = generated
    assert pkg.SPEC.register("demand_period").open_for_writes == ("word_order",)
    sim: Any = importlib.import_module("wopkg.sdm630.simulator").Simulator(units=[1])
    with ThreadedSimServer(sim, tcp=("127.0.0.1", 0)) as server:
        assert server.address is not None
        with pkg.Client.tcp("127.0.0.1", server.address[1], unit=1, timeout=1.0) as client:
            sim.set_raw("phase_1_voltage", 0x4366_8000)  # 230.5 as f32, high word first
            with pytest.warns(ReviewWarning, match=r"phase_1_voltage: its map leaves word_order open for review"):
                assert client.phase_1_voltage.read() == 230.5
            held = sim.get_raw("demand_period")
            sent = client.stats.bytes_sent
            for attempt in (lambda: client.demand_period.write(30),
                            lambda: client.write_by_name("demand_period", 30),
                            lambda: client.write_many([(client.demand_period, 30)])):
                with pytest.raises(OpenForReview, match=r"demand_period is not written: .*word_order open"):
                    attempt()
            assert client.stats.bytes_sent == sent  # nothing went out
            assert sim.get_raw("demand_period") == held


def test_docs_and_esphome_say_it_is_open(tmp_path: Path, generated: tuple[Path, ModuleType]) -> None:
    path, _ = generated
    docs = tmp_path / "docs"
    proc = run("export", str(path), "--format", "docs", "-o", str(docs))
    assert proc.returncode == 0, proc.stderr
    pages = "".join(p.read_text(encoding="utf-8") for p in docs.rglob("*.md"))
    assert "word order open for review (read high word first meanwhile)" in pages
    esp = tmp_path / "esp.yaml"
    proc = run("export", str(path), "--format", "esphome", "-o", str(esp))
    assert proc.returncode == 0, proc.stderr
    text = esp.read_text(encoding="utf-8")
    assert "f32, word order open for review" in text

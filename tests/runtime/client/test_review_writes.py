"""Issue 34, runtime side: a register whose ``review:`` leaves a field open that decides the written
words is never written (the generated client's ``.write()``, ``write_by_name``, ``write_many`` and
``drivemap write`` refuse it with :class:`OpenForReview` naming the fields, nothing is sent); its reads
work and warn once. Against the generated package of a map with review markers and its simulator
served on 127.0.0.1."""

from __future__ import annotations

import importlib
import sys
import warnings
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
#: register -> its review list in the test map (rs232_timeout's unit decides no word: it is written)
REVIEW = {"rs485_timeout": "[scale, unit]", "digital_speed": "[type]", "rs232_timeout": "[unit]"}


def _map(folder: Path) -> Path:
    text = (ROOT / "maps" / "ev.yaml").read_text(encoding="utf-8")
    for name, review in REVIEW.items():
        line = f"\n  - name: {name}\n"
        assert text.count(line) == 1
        text = text.replace(line, f"{line}    review: {review}\n")
    path = folder / "ev.yaml"
    path.write_text(text.replace("../schemas/", str(ROOT / "schemas") + "/"), encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def generated(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Path, ModuleType]]:
    """The map, and the package ``drivemap build`` writes for it (imported from its files)."""
    folder = tmp_path_factory.mktemp("review")
    path = _map(folder)
    out = folder / "out"
    write_tree(out / "reviewpkg", render_tree([compile_map(path)]), force=True)
    sys.path.insert(0, str(out))
    try:
        yield path, importlib.import_module("reviewpkg.ev")
    finally:
        sys.path.remove(str(out))
        for name in [n for n in sys.modules if n == "reviewpkg" or n.startswith("reviewpkg.")]:
            del sys.modules[name]


@pytest.fixture
def served(generated: tuple[Path, ModuleType]) -> Iterator[tuple[Any, int]]:
    sim = importlib.import_module("reviewpkg.ev.simulator").Simulator(units=[1])
    with ThreadedSimServer(sim, tcp=("127.0.0.1", 0)) as server:
        assert server.address is not None
        yield sim, server.address[1]


def _words(sim: Any, name: str, spec: Any) -> list[int]:
    """The raw values the simulated device holds for each element of ``name``."""
    count = spec.register(name).count
    return [sim.get_raw(f"{name}[{i}]" if count > 1 else name, 1) for i in range(count)]


def test_generated_spec_carries_review(generated: tuple[Path, ModuleType]) -> None:
    _, pkg = generated
    text = (Path(pkg.__file__).parent / "spec.py").read_text(encoding="utf-8")
    assert "review=('scale', 'unit')," in text and "review=('type',)," in text
    assert pkg.SPEC.register("rs485_timeout").open_for_writes == ("scale",)
    assert pkg.SPEC.register("rs232_timeout").open_for_writes == ()
    # a map without review markers prints none (sdm630 states every field); ev prints its open signedness
    assert "review=" not in (ROOT / "generated" / "drivemap_models" / "sdm630" / "spec.py").read_text(encoding="utf-8")
    assert "review=('signedness',)," in (ROOT / "generated" / "drivemap_models" / "ev" / "spec.py").read_text(encoding="utf-8")


def test_client_refuses_writes_and_sends_nothing(served: tuple[Any, int], generated: tuple[Path, ModuleType]) -> None:
    sim, port = served
    pkg = generated[1]
    spec = pkg.SPEC
    before = {n: _words(sim, n, spec) for n in REVIEW}
    with pkg.Client.tcp("127.0.0.1", port, unit=1, timeout=1.0) as client:
        sent = client.stats.bytes_sent
        for attempt in (lambda: client.rs485_timeout.write(5),
                        lambda: client.write_by_name("rs485_timeout", 5),
                        lambda: client.write_many([(client.rs485_timeout, 5)]),
                        lambda: client.rs485_timeout.write_raw(5),
                        lambda: client.write_many([(client.rs232_timeout, 7), (client.rs485_timeout, 5)])):
            with pytest.raises(OpenForReview) as info:
                attempt()
            assert info.value.register == "rs485_timeout" and info.value.fields == ("scale",)
            assert "leaves scale open for review" in str(info.value)
        for attempt in (lambda: client.digital_speed[0].write(100),
                        lambda: client.write_by_name("digital_speed[2]", 100),
                        lambda: client.write_by_name("digital_speed", [1] * 8),
                        lambda: client.digital_speed.write([1] * 8)):
            with pytest.raises(OpenForReview, match=r"digital_speed is not written: .* type open"):
                attempt()
        assert client.stats.bytes_sent == sent  # nothing went out
        assert {n: _words(sim, n, spec) for n in REVIEW} == before
        client.rs232_timeout.write(7)  # its open unit decides no word
        assert _words(sim, "rs232_timeout", spec) == [7]


def test_reads_work_and_warn_once(served: tuple[Any, int], generated: tuple[Path, ModuleType]) -> None:
    sim, port = served
    pkg = generated[1]
    with pkg.Client.tcp("127.0.0.1", port, unit=1, timeout=1.0) as client:
        with pytest.warns(ReviewWarning, match=r"rs485_timeout: its map leaves scale open for review") as said:
            first = client.rs485_timeout.read()
        assert said[0].filename == __file__  # attributed to the caller's line, not the runtime's
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            assert client.rs485_timeout.read() == first  # once per register and client
            assert client.read_by_name("rs485_timeout") == first
            client.rs232_timeout.read()  # no open field that decides its value: no warning
        with pytest.warns(ReviewWarning) as caught:
            client.read_all()
        assert sorted(str(w.message).split(":")[0] for w in caught) == ["digital_speed"]
        assert {w.filename for w in caught} == {__file__}


async def _async_refusal(pkg: ModuleType, port: int) -> None:
    async with pkg.AsyncClient.tcp("127.0.0.1", port, unit=1, timeout=1.0) as client:
        with pytest.raises(OpenForReview):
            await client.rs485_timeout.write(5)
        with pytest.raises(OpenForReview):
            await client.write_by_name("digital_speed", [1] * 8)
        with pytest.warns(ReviewWarning):
            await client.digital_speed[1].read()


def test_async_client(served: tuple[Any, int], generated: tuple[Path, ModuleType]) -> None:
    import asyncio

    sim, port = served
    before = _words(sim, "rs485_timeout", generated[1].SPEC)
    asyncio.run(_async_refusal(generated[1], port))
    assert _words(sim, "rs485_timeout", generated[1].SPEC) == before


def test_drivemap_write_refuses_with_located_error(served: tuple[Any, int], generated: tuple[Path, ModuleType]) -> None:
    sim, port = served
    path, pkg = generated
    before = _words(sim, "rs485_timeout", pkg.SPEC)
    for extra in ((), ("--dry-run",)):
        proc = run("write", str(path), "rs232_timeout=3", "rs485_timeout=5", "digital_speed[0]=9", "--tcp",
                   f"127.0.0.1:{port}", "--no-identity-check", *extra)
        assert proc.returncode == 1, proc.stdout
        errors = [line for line in proc.stderr.splitlines() if ": error: " in line]
        assert len(errors) == 2, proc.stderr
        assert "rs485_timeout is not written: its map leaves scale open for review" in errors[0]
        assert "digital_speed is not written: its map leaves type open for review" in errors[1]
        assert "Traceback" not in proc.stderr
    assert _words(sim, "rs485_timeout", pkg.SPEC) == before
    assert _words(sim, "rs232_timeout", pkg.SPEC) != [3]  # nothing of the command was written
    proc = run("write", str(path), "rs232_timeout=3", "--tcp", f"127.0.0.1:{port}", "--no-identity-check")
    assert proc.returncode == 0, proc.stderr
    assert _words(sim, "rs232_timeout", pkg.SPEC) == [3]

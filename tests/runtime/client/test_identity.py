"""A map's ``identity``: the registers and values that say which device answers.

`scan` judges a map by its identity registers first; `write` refuses a device that does not match
(naming the register and both values) unless `--no-identity-check`; `read` warns; the runtime's
``check_identity`` does the same for programs (and the gateway)."""

from __future__ import annotations

import asyncio
import json
from pathlib import Path
from types import SimpleNamespace

import pytest
from helpers_client import package, simulator, tcp_server
from helpers_live import ROOT, no_traceback, run

from drivemap.compiler import compile_map
from drivemap.runtime.client.api.identity import check_identity, check_identity_async
from drivemap.runtime.errors import IdentityMismatch

SHIPPED = sorted(p.stem for p in (ROOT / "maps").glob("*.yaml"))


#: Settings a simulator starts at 0 where the map's own range excludes 0 (the manual prints no factory
#: default), set as a configured device would hold them, so that the read fingerprint can fit.
CONFIGURED = {"sdm630": {"system_type": 3.0}}


@pytest.mark.parametrize("model", SHIPPED)
def test_scan_finds_every_shipped_simulator_by_identity_first(model: str) -> None:
    sim = simulator(model, (5,))
    for name, value in CONFIGURED.get(model, {}).items():
        sim.set(name, value)
    with tcp_server(model, sim=sim) as (_, host, port):
        proc = run("scan", "--tcp", f"{host}:{port}", "--units", "5", "--json")
    no_traceback(proc)
    assert proc.returncode == 0, proc.stderr
    fits = json.loads(proc.stdout)["units"][0]["fits"]
    first = fits[0]
    assert first["model"] == model and first["fits"], fits
    has_identity = bool(compile_map(ROOT / "maps" / f"{model}.yaml").identity)
    assert first["by"] == ("identity" if has_identity else "fingerprint")
    for other in fits[1:]:
        assert not other["fits"] or other["by"] == "fingerprint", other  # no second map matches by identity


def test_maps_that_state_identity() -> None:
    """The shipped maps whose sources state an identifying register carry it (SunSpec's 'SunS')."""
    fronius = compile_map(ROOT / "maps" / "fronius_symo_hybrid.yaml")
    marker = next(c for c in fronius.identity if c.register == "sunspec_id")
    assert marker.values == (0x53756E53,) and marker.expected() == "0x53756E53 ('SunS')"
    assert {c.register for c in fronius.identity} == {"sunspec_id", "common_model_id", "manufacturer",
                                                      "inverter_model_id"}


def test_the_json_export_carries_identity() -> None:
    from drivemap.backends.export import export

    data = export(compile_map(ROOT / "maps" / "fronius_symo_hybrid.yaml"))
    assert data["identity"][0] == {"register": "sunspec_id", "kind": "equals", "values": [0x53756E53],
                                   "source": "IntSF 'Complete Map' 40001-40002 (SID, range of values 0x53756e53); 2049 p.82"}
    assert export(compile_map(ROOT / "maps" / "ev.yaml"))["identity"] == []


def test_runtime_check_identity_names_register_and_both_values() -> None:
    mod = package("fronius_symo_hybrid")
    with tcp_server("fronius_symo_hybrid") as (sim, host, port):
        client = mod.Client.tcp(host, port, 1)
        try:
            assert check_identity(client) == ()
            assert check_identity(SimpleNamespace(client=client)) == ()  # anything holding a client
            sim.unit(1).values["inverter_model_id"] = 113  # the float map's model id
            with pytest.raises(IdentityMismatch) as err:
                check_identity(client)
            found = check_identity(client, raise_on_mismatch=False)
        finally:
            client.close()
    text = str(err.value)
    assert "inverter_model_id" in text and "holds 113" in text and "one of 101, 102, 103" in text
    assert [m.register for m in found] == ["inverter_model_id"]


def test_async_check_identity() -> None:
    mod = package("fronius_symo_hybrid")

    async def run(host: str, port: int) -> str:
        client = mod.AsyncClient.tcp(host, port, 1)
        try:
            assert await check_identity_async(client) == ()
            sim.unit(1).values["manufacturer"] = int.from_bytes(b"SMA".ljust(32, b"\0"), "big")
            with pytest.raises(IdentityMismatch) as err:
                await check_identity_async(client)
            return str(err.value)
        finally:
            client.close()

    with tcp_server("fronius_symo_hybrid") as (sim, host, port):
        text = asyncio.run(run(host, port))
    assert "manufacturer" in text and "'SMA'" in text and "'Fronius'" in text


def test_write_refuses_a_device_that_is_not_the_maps(tmp_path: Path) -> None:
    sim = simulator("fronius_symo_hybrid")
    sim.unit(1).values["sunspec_id"] = 0x12345678
    with tcp_server("fronius_symo_hybrid", sim=sim) as (_, host, port):
        refused = run("write", "fronius_symo_hybrid", "f_store_data=0xFFFF", "--tcp", f"{host}:{port}")
        untouched = sim.unit(1).values["f_store_data"]
        forced = run("write", "fronius_symo_hybrid", "f_store_data=0xFFFF", "--tcp", f"{host}:{port}",
                     "--no-identity-check", "--no-read-back")
        read = run("read", "fronius_symo_hybrid", "common_model_id", "--tcp", f"{host}:{port}")
    no_traceback(refused)
    assert refused.returncode == 7, refused.stderr
    line = refused.stderr.strip().splitlines()[-1]
    assert line.startswith("drivemap write: error: unit 1 is not a fronius_symo_hybrid: sunspec_id")
    assert "holds 0x12345678" in line and "expects 0x53756E53 ('SunS')" in line and "nothing was written" in line
    assert untouched == 0
    assert forced.returncode == 0, forced.stderr
    assert sim.unit(1).values["f_store_data"] == 0xFFFF
    assert read.returncode == 0 and "warning: unit 1 is not a fronius_symo_hybrid" in read.stderr


def test_verify_reports_an_identity_disagreement(tmp_path: Path) -> None:
    sim = simulator("fronius_symo_hybrid")
    sim.unit(1).values["common_model_id"] = 2
    with tcp_server("fronius_symo_hybrid", sim=sim) as (_, host, port):
        proc = run("verify", "fronius_symo_hybrid", "--tcp", f"{host}:{port}", "--report", str(tmp_path / "v"))
        refused = run("verify", "fronius_symo_hybrid", "--tcp", f"{host}:{port}", "--write-safe",
                      "--report", str(tmp_path / "w"))
    no_traceback(proc)
    assert proc.returncode == 6, proc.stderr
    report = json.loads((tmp_path / "v.json").read_text(encoding="utf-8"))
    found = [f for f in report["findings"] if f["check"] == "identity"]
    assert [(f["subject"], f["map_says"], f["device_says"]) for f in found] == [("common_model_id", "1", "2")]
    assert refused.returncode == 7 and "common_model_id" in refused.stderr and "nothing was written" in refused.stderr
    assert not (tmp_path / "w.json").exists()

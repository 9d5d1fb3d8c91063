"""The evcc, ha-solarman and modbus_local_gateway importers on small fixtures of our own, and
(corpus tier) every file of ../shared/catalogue-sources rebuilt and compared with maps/catalogue/."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest
import yaml

from drivemap.cli import main

ROOT = Path(__file__).resolve().parents[3]
FIX = ROOT / "tests" / "fixtures" / "catalogue"


def _import(tmp_path: Path, fmt: str, name: str, model: str) -> dict:  # type: ignore[type-arg]
    out = tmp_path / f"{model}.yaml"
    assert main(["import", fmt, str(FIX / name), "-o", str(out)]) == 0
    assert main(["validate", str(out)]) == 0
    data: dict = yaml.safe_load(out.read_text(encoding="utf-8"))  # type: ignore[type-arg]
    return data


def test_evcc_usages_become_registers(tmp_path: Path) -> None:
    data = _import(tmp_path, "evcc", "meter.yaml", "acme")
    regs = {r["name"]: r for r in data["registers"]}
    assert regs["grid_power"]["table"] == "input" and regs["grid_power"]["address"] == 10
    assert regs["grid_power"]["type"] == "s32" and regs["grid_power"]["word_order"] == "low_first"
    assert regs["grid_power"]["scale"] == 0.1 and regs["grid_power"]["unit"] == "W"
    assert regs["pv_energy"]["type"] == "f32" and regs["pv_energy"]["unit"] == "kWh"
    assert data["device"]["evidence"] == "imported" and data["device"]["kind"] == "inverter"


def test_solarman_rules_lookups_and_left_out(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data = _import(tmp_path, "ha-solarman", "profile.yaml", "inv")
    regs = {r["name"]: r for r in data["registers"]}
    assert regs["grid_power"]["type"] == "s32" and regs["grid_power"]["word_order"] == "low_first"
    assert regs["grid_power"]["table"] == "input"
    enum = data["enums"][regs["state"]["enum"]]["values"]
    assert [v["value"] for v in enum] == [0, 1, 2]
    assert "profile.yaml:" in capsys.readouterr().out  # the computed item is listed with its line


def test_mlg_types_and_open_offset(tmp_path: Path) -> None:
    data = _import(tmp_path, "modbus-local-gateway", "gateway.yaml", "g1")
    regs = {r["name"]: r for r in data["registers"]}
    assert regs["voltage"]["type"] == "f32" and regs["voltage"]["word_order"] == "high_first"
    assert regs["temp"]["review"] == ["offset"] and "offset" not in regs["temp"]


def test_evcc_unsupported_feature_is_a_located_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "m.yaml"
    src.write_text("template: x\nrender: |\n  type: mbmd\n  model: sdm\n", encoding="utf-8")
    assert main(["import", "evcc", str(src), "-o", str(tmp_path / "x.yaml")]) == 1
    assert "m.yaml:3:3: error: the template renders mbmd" in capsys.readouterr().err


@pytest.mark.corpus
def test_catalogue_rebuilds_from_the_sources(tmp_path: Path) -> None:
    shared = Path(os.environ.get("DRIVEMAP_SHARED") or ROOT.parent / "shared")
    assert (shared / "catalogue-sources").is_dir(), f"{shared}/catalogue-sources is missing (set DRIVEMAP_SHARED)"
    sys.path.insert(0, str(ROOT / "bench"))
    from drivemap.onboard.importers.catalogue import build

    outcomes = build(shared, tmp_path, {p.stem for p in (ROOT / "maps").glob("*.yaml")}, ROOT)
    for o in outcomes:
        assert o.written or (o.error and ": error: " in o.error), o
    written = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*.yaml"))
    committed = sorted(p.relative_to(ROOT / "maps" / "catalogue") for p in (ROOT / "maps" / "catalogue").rglob("*.yaml"))
    assert written == committed and len(written) >= 100
    for rel in written:
        assert (tmp_path / rel).read_text(encoding="utf-8") == (ROOT / "maps" / "catalogue" / rel).read_text(
            encoding="utf-8"), rel


def test_pairing_rule_pairs_one_model_never_two() -> None:
    from drivemap.onboard.importers.pairs import Entry, designations, pairs

    assert designations("Eastron SDM630-Modbus three-phase meter") == designations("Eastron SDM-630") == {"sdm630"}
    entries = [
        Entry("maps/sdm630.yaml", "project", "Eastron", "Eastron SDM630-Modbus meter", "sdm630"),
        Entry("sdm630_mlg", "mlg", "Eastron", "Eastron SDM-630", "SDM630"),
        Entry("sdm120", "evcc", "Eastron", "Eastron SDM120-Modbus", "eastron-sdm120"),
        Entry("min_xe", "evcc", "Growatt", "Growatt MIN 3000TL-XE", "growatt-min-tlxe"),
        Entry("min_xh", "mlg", "Growatt", "Growatt MIN 6000TL-XH", "MIN_6000TL-XH"),
        Entry("solis_hybrid", "evcc", "Ginlong", "Ginlong Solis Hybrid Inverter", "solis-hybrid"),
        Entry("solis_hybrid_2", "ha_solarman", None, "solis_hybrid", "solis_hybrid"),
        Entry("other_hybrid", "ha_solarman", None, "other_hybrid", "solis_hybrid_x"),
        Entry("deye_hybrid", "mlg", "Deye", "Deye hybrid", "solis-hybrid"),  # another vendor, same name
        Entry("sunspec_common", "sunspec", None, "SunSpec model 1", "sdm630"),
        Entry("sdm630_again", "mlg", "Eastron", "Eastron SDM630 v2", "sdm630b"),  # one source: not paired
    ]
    found = {(a.model, b.model) for a, b, _ in pairs(entries)}
    assert found == {("maps/sdm630.yaml", "sdm630_mlg"), ("solis_hybrid", "solis_hybrid_2")}


@pytest.mark.corpus
def test_every_pair_of_one_device_is_compared_and_recorded(tmp_path: Path) -> None:
    """The real catalogue: the pairs the rule finds, and each disagreement a known issue of the imported map."""
    shared = Path(os.environ.get("DRIVEMAP_SHARED") or ROOT.parent / "shared")
    assert (shared / "catalogue-sources").is_dir(), f"{shared}/catalogue-sources is missing (set DRIVEMAP_SHARED)"
    from drivemap.compiler import compile_map
    from drivemap.onboard.compare import compare_models
    from drivemap.onboard.importers.catalogue import Pair, build

    found: list[Pair] = []
    build(shared, tmp_path, {p.stem for p in (ROOT / "maps").glob("*.yaml")}, ROOT, found)
    assert {(p.a, p.b) for p in found} == {
        ("maps/sdm630.yaml", "sdm630_modbus_local_gateway"), ("afore_hybrid", "afore_hybrid_ha_solarman"),
        ("deye_hybrid_3p", "deye_p3"), ("deye_string", "deye_string_ha_solarman"),
        ("solis_hybrid", "solis_hybrid_ha_solarman")}
    files = {p.stem: p for p in tmp_path.rglob("*.yaml")}
    recorded = 0
    for pair in found:
        for mine, other in ((pair.a, pair.b), (pair.b, pair.a)):
            if mine.startswith("maps/"):
                continue
            other_path = ROOT / other if other.startswith("maps/") else files[other]
            diffs = compare_models(compile_map(files[mine]), compile_map(other_path))
            data = yaml.safe_load(files[mine].read_text(encoding="utf-8"))
            printed = " ".join(k["printed"] for k in data.get("known_issues") or [])
            assert all(d.line() in printed for d in diffs), mine
            recorded += len(diffs)
    assert recorded >= 5  # afore (1 each way) and deye 3p (4 + more) disagree today

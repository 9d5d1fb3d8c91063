"""The exports keep what a map leaves open as open: unknown broadcast, review markers (a warning in every
export, no write control while a write-deciding field is open), the evidence level and origin."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import yaml
from exporter_helpers import ROOT, load, parse, render

from drivemap.backends.common import Options
from drivemap.backends.export import export
from drivemap.backends.exporters import available
from drivemap.compiler import compile_map

FORMATS = ("homeassistant", "esphome", "csv", "pymodbus-sim", "docs")


def _map(tmp: Path, model: str, edit: Any) -> Path:
    data = yaml.safe_load((ROOT / "maps" / f"{model}.yaml").read_text(encoding="utf-8"))
    edit(data)
    path = tmp / f"{model}.yaml"
    path.write_text(yaml.safe_dump(data, allow_unicode=True, sort_keys=False), encoding="utf-8")
    return path


def _register(data: dict[str, Any], name: str) -> dict[str, Any]:
    return next(r for r in data["registers"] if r["name"] == name)


def test_json_keeps_unknown_broadcast_unknown() -> None:
    """wattnode's write functions say broadcast: null: its writable registers are not 'false'."""
    regs = export(load("wattnode_wnc"))["registers"]
    writable = [r for r in regs if "w" in r["access"]]
    assert writable and all(r["broadcast"] is None for r in writable)
    assert all(r["broadcast"] is False for r in regs if "w" not in r["access"])
    # the manual says the meter has no broadcast (function codes broadcast: false): still false
    assert all(r["broadcast"] is False for r in export(load("sdm630"))["registers"])


def test_json_review_and_provenance_only_where_stated(tmp_path: Path) -> None:
    plain = export(load("ev"))
    assert plain["evidence"] == "manual" and plain["kind"] == "drive" and "origin" not in plain
    assert [r["review"] for r in plain["registers"] if r["name"] == "servo_on_mode"] == [["signedness"]]
    assert "review" not in next(r for r in plain["registers"] if r["name"] == "motor_state")
    assert list(plain)[:5] == ["model", "title", "evidence", "kind", "protocol"]

    def edit(data: dict[str, Any]) -> None:
        del data["device"]["evidence"], data["device"]["kind"]
        data["device"]["origin"] = {"project": "someone/defs", "path": "ev.yaml", "commit": "abc123", "licence": "MIT"}
        _register(data, "servo_on_mode")["review"] = ["type", "unit"]

    doc = export(compile_map(_map(tmp_path, "ev", edit)))
    assert "evidence" not in doc and "kind" not in doc
    assert doc["origin"] == {"project": "someone/defs", "path": "ev.yaml", "commit": "abc123", "licence": "MIT",
                             "format": None}
    reviewed = [r for r in doc["registers"] if "review" in r]
    assert ("servo_on_mode", ["type", "unit"]) in [(r["name"], r["review"]) for r in reviewed]
    assert len(reviewed) == sum(r.count for r in load("ev").registers if r.review)


def test_open_fields_warn_in_every_export_and_keep_writes_out(tmp_path: Path) -> None:
    model = load("ev")
    before = {fmt: render(model, fmt) for fmt in FORMATS}
    assert all("digital_speed: type open" not in text for text in before.values())
    assert "ev digital_speed_0" in [e["name"] for e in parse("esphome", before["esphome"])["number"]]

    def edit(data: dict[str, Any]) -> None:
        _register(data, "digital_speed")["review"] = ["type"]
        _register(data, "sc_cc_mode")["review"] = ["unit"]  # not write-deciding: the control stays

    reviewed = compile_map(_map(tmp_path, "ev", edit))
    after = {fmt: render(reviewed, fmt) for fmt in FORMATS}
    warning = "digital_speed: type open in the map's source (no write: it decides what a write sends)"
    for fmt in ("homeassistant", "esphome"):
        assert f"# review: {warning}\n" in after[fmt], fmt
        assert "# review: sc_cc_mode: unit open in the map's source\n" in after[fmt], fmt
    esphome = parse("esphome", after["esphome"])
    assert "ev digital_speed_0" not in [e["name"] for e in esphome["number"]]
    assert "ev sc_cc_mode" in [e["name"] for e in esphome["select"]]
    assert "ev digital_speed_0" in [e.get("name") for e in esphome["sensor"]]  # still read
    rows = {r["name"]: r for r in parse("csv", after["csv"])}
    assert rows["digital_speed[0]"]["review"] == warning and rows["motor_state"]["review"] == ""
    sim = json.loads(after["pymodbus-sim"])["drivemap"]
    added = {"review: sc_cc_mode: unit open in the map's source", f"review: {warning}"}
    assert added <= set(sim["review"]) and not added & set(json.loads(before["pymodbus-sim"])["drivemap"]["review"])
    assert "- " + warning.replace("_", "\\_") + "\n" in after["docs"]


def test_every_export_header_names_the_evidence(tmp_path: Path) -> None:
    model = load("sdm630")
    assert "# evidence: manual; kind: meter\n" in render(model, "homeassistant")
    assert "# evidence: manual; kind: meter\n" in render(model, "esphome")
    assert json.loads(render(model, "pymodbus-sim"))["drivemap"]["provenance"] == ["evidence: manual; kind: meter"]
    assert "**Evidence:** manual; kind: meter" in render(model, "docs")
    assert {(r["evidence"], r["origin_project"]) for r in parse("csv", render(model, "csv"))} == {("manual", "")}
    files = available()["python"]().render(model, Options(root=ROOT, values={"package": "drivemap_models"}))
    for name in ("sdm630/client.py", "sdm630/__init__.py", "sdm630/spec.py", "sdm630/simulator.py"):
        assert files[name].split("\n")[2] == "evidence: manual; kind: meter", name  # in the module docstring

    def edit(data: dict[str, Any]) -> None:
        del data["device"]["evidence"]
        data["device"]["origin"] = {"project": "x/y", "path": "m.json", "commit": "c0ffee", "licence": "MIT",
                                    "format": "modeljson"}

    other = compile_map(_map(tmp_path, "sdm630", edit))
    text = render(other, "homeassistant")
    assert "# evidence: not stated by the map; kind: meter\n# origin: x/y m.json at c0ffee (MIT; imported as modeljson)\n" \
        in text
    rows = parse("csv", render(other, "csv"))
    assert {(r["evidence"], r["origin_project"], r["origin_path"], r["origin_commit"], r["origin_licence"],
             r["origin_format"]) for r in rows} == {("", "x/y", "m.json", "c0ffee", "MIT", "modeljson")}
    client = available()["python"]().render(other, Options(root=ROOT, values={"package": "p"}))["sdm630/client.py"]
    assert client.split("\n")[2:4] == ["evidence: not stated by the map; kind: meter",
                                       "origin: x/y m.json at c0ffee (MIT; imported as modeljson)"]
    index = (ROOT / "generated" / "docs" / "index.md").read_text(encoding="utf-8")
    assert "| Evidence | Origin |" in index
    assert "| manual | the map's manual |" in index


def test_sdm630_reset_names_the_two_word_list() -> None:
    text = render(load("sdm630"), "homeassistant")
    assert ("# not exported as a switch: reset (a switch writes one register; use the modbus.write_register action "
            "with value: [0, 0], the 2-word list, sent as 10h; a single number goes out as 06h to one register)\n") in text


def test_solax_bdc_status_keeps_the_value_after_the_page_break() -> None:
    model = load("solax_x1x3_g4")
    assert [(m.value, m.label) for m in model.enum("BdcStatus").members] == [(0, "discharge"), (1, "charge"),
                                                                             (2, "stop")]
    assert "@ 19bd26593e4a7bab7ef68e3ef0ebf0225d07c57f :" in (model.device.manual.file or "")


def test_delta_reply_frames_are_checked_examples() -> None:
    for name in ("delta_vfd_el_w", "delta_vfd_f"):
        examples = {ex.name: ex for ex in load(name).examples}
        assert examples["exception_reply_rtu"].response == "01 86 02 C3 A1"
        assert examples["exception_reply_ascii"].response == ":01860277\r\n"
        assert all(ex.status == "verified" for ex in examples.values())

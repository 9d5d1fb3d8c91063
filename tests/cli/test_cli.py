"""The drivemap command: validate, build, check, examples, export, new."""

from __future__ import annotations

import contextlib
import io
import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from drivemap.cli import main

ROOT = Path(__file__).resolve().parents[2]
MAPS = sorted(p.stem for p in (ROOT / "maps").glob("*.yaml"))


def run(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(list(argv))
    return code, out.getvalue(), err.getvalue()


@pytest.fixture(autouse=True)
def _at_root(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(ROOT)


def test_validate_every_map() -> None:
    code, out, err = run("validate")
    assert code == 0, err
    assert [line.split(":")[0] for line in out.splitlines()] == [f"maps/{m}.yaml" for m in MAPS]


def test_build_prints_one_line_per_model_and_check_sees_staleness(tmp_path: Path) -> None:
    out_dir = tmp_path / "generated"
    code, out, err = run("build", "--out", str(out_dir))
    assert code == 0, err
    lines = out.splitlines()
    for model in MAPS:
        assert sum(line.startswith(f"{model}: ") for line in lines) == 1
    assert run("check", "--out", str(out_dir))[0] == 0
    # a hand edit and a deleted file are reported; a file drivemap did not write is the user's
    client = out_dir / "ev" / "client.py"
    client.write_text(client.read_text(encoding="utf-8") + "# edited\n", encoding="utf-8")
    (out_dir / "v2" / "spec.py").unlink()
    (out_dir / "edx" / "helper.py").write_text("# mine\n", encoding="utf-8")
    code, _, err = run("check", "--out", str(out_dir))
    assert code == 1
    assert "ev/client.py: differs" in err
    assert "v2/spec.py: missing" in err
    assert "helper.py" not in err
    # build repairs drivemap's files, says which had been edited, and keeps the user's
    code, out, _ = run("build", "--out", str(out_dir))
    assert code == 0 and "ev/client.py: it had been edited by hand" in out
    assert run("check", "--out", str(out_dir))[0] == 0
    assert (out_dir / "edx" / "helper.py").read_text(encoding="utf-8") == "# mine\n"


def test_committed_generated_tree_is_current() -> None:
    code, _, err = run("check")
    assert code == 0, err


def test_build_is_deterministic(tmp_path: Path) -> None:
    run("build", "--out", str(tmp_path / "a"))
    run("build", "--out", str(tmp_path / "b"))
    for path in sorted((tmp_path / "a").rglob("*")):
        if path.is_file():
            twin = tmp_path / "b" / path.relative_to(tmp_path / "a")
            assert path.read_bytes() == twin.read_bytes(), path


def test_examples_table() -> None:
    code, out, _ = run("examples", "edx")
    assert code == 0
    assert "error_code_rtu" in out and "erratum" in out
    assert out.splitlines()[-1].startswith("edx: frames 18, ")


def test_examples_unknown_model() -> None:
    code, _, err = run("examples", "nosuch")
    assert code == 1
    assert "maps/nosuch.yaml:1:1: error: no map for model 'nosuch'" in err


@pytest.mark.parametrize("model", MAPS)
def test_export_contract(model: str) -> None:
    code, out, _ = run("export", model, "--format", "json")
    assert code == 0
    data = json.loads(out)
    required = {"model", "title", "protocol", "registers", "reserved", "known_issues", "identity", "examples"}
    assert required <= set(data) <= required | {"evidence", "kind", "origin"}  # provenance: where the map states it
    assert data["model"] == model
    keys = {"name", "address", "param", "access", "type", "scale", "offset", "unit", "min", "max", "default",
            "reflect", "storage", "broadcast", "enum", "bits", "page", "table", "length", "word_order", "byte_order",
            "encoding", "scale_register", "not_available"}
    for reg in data["registers"]:
        assert keys <= set(reg) <= keys | {"review"}  # review: only where the map leaves fields open
        assert reg["access"] in ("r", "w", "rw") and reg["type"] in ("u16", "s16", "u32", "s32", "u64", "s64",
                                                                     "f32", "f64", "string", "bool")
        assert reg["table"] in ("holding", "input", "coil", "discrete") and reg["length"] >= 1
        assert reg["byte_order"] in ("high_first", "low_first")
        assert reg["reflect"] in ("immediate", "configuration", "power_cycle", None)
        assert reg["storage"] in ("eeprom", "ram", "volatile", None)
        assert reg["broadcast"] in (True, False, None)  # None: the map does not say (kept unknown)
    for item in data["reserved"]:
        assert set(item) == {"start", "end", "readable", "writable", "page", "table", "kind", "source"}
        assert item["table"] in ("holding", "input", "coil", "discrete")
        assert item["kind"] in ("reserved", "unlabeled", "not_listed")
        assert item["start"] <= item["end"] and item["readable"] in (True, False, None)
    for issue in data["known_issues"]:
        assert set(issue) == {"title", "source", "printed", "corrected", "chosen", "reason", "affects"}
    for ex in data["examples"]:
        assert set(ex) == {"name", "source", "mode", "request", "response", "status", "erratum", "corrected_request",
                           "corrected_response"}
        assert (ex["corrected_request"] is not None or ex["corrected_response"] is not None) == (ex["status"] == "erratum")
        for frame in (ex["request"], ex["response"], ex["corrected_request"], ex["corrected_response"]):
            if frame is not None and ex["mode"] == "rtu":
                assert " " not in frame and frame == frame.upper()
            if frame is not None and ex["mode"] == "ascii":
                assert frame.startswith(":") and frame.endswith("\r\n")


def test_export_named_registers() -> None:
    data = json.loads(run("export", "ev")[1])
    regs = {r["name"]: r for r in data["registers"]}
    assert regs["bus_voltage"]["address"] == 0x0009 and regs["bus_voltage"]["scale"] == 0.01
    assert regs["digital_speed[7]"]["address"] == 0x030F and regs["digital_speed[0]"]["storage"] == "eeprom"
    assert regs["digital_speed_ram[0]"]["address"] == 0x3F08 and regs["digital_speed_ram[0]"]["storage"] == "ram"
    assert regs["net_in"]["bits"][0] == {"name": "X0", "offset": 0, "width": 1}


def test_new_scaffold_validates_and_refuses_to_overwrite() -> None:
    target = ROOT / "maps" / "foo.yaml"
    assert not target.exists()
    try:
        assert run("new", "foo")[0] == 0
        text = target.read_text(encoding="utf-8")
        assert text.startswith("# yaml-language-server: $schema=../schemas/drivemap.schema.json")
        code, _, err = run("validate", "maps/foo.yaml")
        assert code == 0, err
        code, _, err = run("new", "foo")
        assert code == 1 and "file exists" in err
    finally:
        target.unlink(missing_ok=True)


def test_new_refuses_bad_model_id() -> None:
    code, _, err = run("new", "Bad-Name")
    assert code == 1 and "must be a lower-case identifier" in err


def test_console_script_exit_codes(tmp_path: Path) -> None:
    exe = shutil.which("drivemap")
    cmd = [exe] if exe else [sys.executable, "-m", "drivemap.cli"]
    bad = tmp_path / "bad.yaml"
    bad.write_text("drivemap: 1\n", encoding="utf-8")
    proc = subprocess.run([*cmd, "validate", str(bad)], capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert proc.returncode == 1
    assert "Traceback" not in proc.stderr
    assert proc.stderr.startswith(f"{bad}:1:1: error: ")

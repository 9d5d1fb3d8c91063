"""What a first-time user meets at the command line: which map a verb uses, the exporter's own options
in --help, an error that says what to write, what --write-safe left alone, -o FILE writing only FILE."""

from __future__ import annotations

import json
from pathlib import Path

from helpers_client import tcp_server
from helpers_live import ROOT, no_traceback, run


def test_a_shipped_map_is_named_and_a_differing_project_map_is_a_warning(tmp_path: Path) -> None:
    proc = run("write", "sdm630", "--dry-run", "--tcp", "127.0.0.1:9", "demand_period=30", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "'sdm630' is not a map of the project" in proc.stderr and "shipped with drivemap" in proc.stderr
    assert "sdm630.yaml" in proc.stderr
    (tmp_path / "maps").mkdir()
    text = (ROOT / "maps" / "sdm630.yaml").read_text(encoding="utf-8").replace("title: ", "title: My ", 1)
    (tmp_path / "maps" / "sdm630.yaml").write_text(text, encoding="utf-8")
    proc = run("export", "sdm630", "--format", "json", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    warning = next(line for line in proc.stderr.splitlines() if ": warning:" in line)
    assert warning.startswith("maps/sdm630.yaml:1:1: warning:") and "shipped with drivemap" in warning
    assert "using the project's" in warning
    same = run("export", "ev", "--format", "json")  # this repository: the project's map is the shipped one
    assert same.returncode == 0 and "warning" not in same.stderr and "note" not in same.stderr, same.stderr


def test_export_help_lists_the_exporters_options() -> None:
    proc = run("export", "--format", "homeassistant", "--help")
    assert proc.returncode == 0, proc.stderr
    for option in ("--baudrate", "--tcp", "--hub-name", "--unit", "--ha-version"):
        assert option in proc.stdout, option
    esphome = run("export", "--format", "esphome", "--help")
    assert "--no-network" in esphome.stdout
    missing = run("export", "fronius_symo_hybrid", "--format", "homeassistant")
    no_traceback(missing)
    assert missing.returncode == 1 and "drivemap export --format homeassistant --help" in missing.stderr
    bad = run("export", "ev", "--format", "homeassistant", "--bogus")
    assert bad.returncode == 1 and "--help" in bad.stderr and "--bogus" in bad.stderr


def test_the_documented_error_says_what_to_write_and_why(tmp_path: Path) -> None:
    text = (ROOT / "maps" / "ev.yaml").read_text(encoding="utf-8")
    first = '      comm_errors: [0x88]\n      source: "001 §2.2"'
    assert text.count(first) == 1
    (tmp_path / "wrong").mkdir()
    wrong_source = tmp_path / "wrong" / "ev.yaml"
    wrong_source.write_text(text.replace(first, first.replace("      source", "      documented: false\n      source")),
                            encoding="utf-8")
    proc = run("validate", str(wrong_source))
    assert proc.returncode == 1, proc.stderr
    line = next(x for x in proc.stderr.splitlines() if ": error:" in x)
    assert "write source: map choice" in line and "the manual prints" in line, line
    # a map choice without `documented` is an assumed code (documented defaults to false): valid
    (tmp_path / "chosen").mkdir()
    chosen = tmp_path / "chosen" / "ev.yaml"
    chosen.write_text(text.replace(first, '      comm_errors: [0x88]\n      source: map choice'), encoding="utf-8")
    assert run("validate", str(chosen)).returncode == 0


def test_verify_write_safe_says_what_it_skipped_and_why(tmp_path: Path) -> None:
    with tcp_server("ev") as (_sim, host, port):
        proc = run("verify", "ev", "--tcp", f"{host}:{port}", "--report", str(tmp_path / "r"), "--write-safe")
    no_traceback(proc)
    assert "--write-safe did not write" in proc.stdout and "stored in EEPROM" in proc.stdout, proc.stdout
    doc = json.loads((tmp_path / "r.json").read_text(encoding="utf-8"))
    skipped = [t for t in doc["not_checked"] if "not written by --write-safe" in t]
    assert any("a command register" in t or "a page selector" in t for t in skipped), skipped
    assert any(t.startswith("digital_speed[0]: ") and "EEPROM" in t for t in skipped), skipped


def test_export_to_one_file_writes_only_that_file(tmp_path: Path) -> None:
    target = tmp_path / "ev.csv"
    proc = run("export", "ev", "--format", "csv", "-o", str(target))
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ev.csv"]
    again = run("export", "ev", "--format", "csv", "-o", str(target))  # the same content: fine
    assert again.returncode == 0, again.stderr
    mine = tmp_path / "mine.yaml"
    mine.write_text("my own notes\n", encoding="utf-8")
    refused = run("export", "ev", "--format", "homeassistant", "--baudrate", "9600", "--method", "rtu", "-o", str(mine))
    assert refused.returncode == 1 and "not written by drivemap" in refused.stderr
    assert mine.read_text(encoding="utf-8") == "my own notes\n"
    ha = tmp_path / "ev.homeassistant.yaml"
    for _ in range(2):  # drivemap's own file (its header says so) is rewritten
        proc = run("export", "ev", "--format", "homeassistant", "--baudrate", "9600", "--method", "rtu", "-o", str(ha))
        assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ev.csv", "ev.homeassistant.yaml", "mine.yaml"]

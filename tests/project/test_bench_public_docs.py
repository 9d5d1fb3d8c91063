"""bench/publicdocs.py: a document that is absent or has another sha256 gives a "not measured" row (never
a number), a draft is measured against its finished map, and hand edits are counted apart from the map's
systematic choices."""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path
from typing import Any

import yaml

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "bench"))

import publicdocs  # noqa: E402
from draftscore import Drafted, compare, make_draft  # noqa: E402

from drivemap.compiler import compile_map  # noqa: E402
from drivemap.frontend.load import load_text  # noqa: E402

HEAD = """\
drivemap: 2
device:
  model: {model}
  title: tiny
  vendor: null
  manual: {{file: dev.csv, document: null, revision: null, date: null, language: en}}
  coverage: a test map
  source: dev.csv
protocol:
  modes: [rtu]
  unit_ids: {{min: 1, max: 247, source: test}}
  broadcast_address: null
  ports:
  - {{name: serial, modes: [rtu], baudrates: [], default_baudrate: null, parity: [], default_parity: null,
     data_bits: [], stop_bits: [], set_by: unknown, source: test}}
  function_codes:
  - {{code: 3, name: read holding registers, max_quantity: null, broadcast: null, broadcast_reason: test, source: test}}
  - {{code: 6, name: write single register, max_quantity: null, broadcast: null, broadcast_reason: test, source: test}}
  exceptions: []
  timing: {{silent_interval_chars: null, response_timeout_ms: null, retries: null, source: test}}
  source: test
enums: {{}}
groups:
- {{name: g, title: G, source: test}}
"""


def reg(name: str, address: int, **fields: Any) -> dict[str, Any]:
    return {"name": name, "label": name, "address": address, "group": "g", "source": "dev.csv row 1", **fields}


def write_map(path: Path, registers: list[dict[str, Any]]) -> Path:
    text = HEAD.format(model=path.stem) + yaml.safe_dump({"registers": registers, "examples": []}, sort_keys=False)
    path.write_text(text, encoding="utf-8")
    return path


def drafted_from(path: Path) -> Drafted:
    text = path.read_text(encoding="utf-8")
    return Drafted(text, load_text(text, str(path)).data, compile_map(path), 0.5)


def finished(path: Path) -> tuple[dict[str, Any], Any]:
    return load_text(path.read_text(encoding="utf-8"), str(path)).data, compile_map(path)


DRAFT = [reg("speed", 100, scale=0.1, unit="Hz"), reg("current", 101, scale=0.01, unit="A"),
         reg("mode", 102, access="rw"), reg("temp", 103, type="s16"), reg("junk", 110)]


def test_hand_edits_apart_from_the_map_choices(tmp_path: Path) -> None:
    """Finished with address - 1 and table holding on every register (the map choices), one scale changed,
    one register renamed with a default added, a unit added, one drafted register dropped, one added."""
    drafted = drafted_from(write_map(tmp_path / "draft.yaml", DRAFT))
    data, model = finished(write_map(tmp_path / "done.yaml", [
        reg("speed", 99, table="holding", scale=0.1, unit="Hz"),
        reg("current", 100, table="holding", scale=0.001, unit="A"),
        reg("op_mode", 101, table="holding", access="rw", default=0),
        reg("temp", 102, table="holding", type="s16", unit="V"),
        reg("alarm", 120, table="holding")]))
    edits = publicdocs.hand_edits(drafted, data, model, offset=-1, table="holding")
    assert edits.added == ["alarm"] and edits.dropped == ["junk"]
    assert sorted(edits.fields) == ["current.scale", "op_mode.default", "op_mode.name", "temp.unit"]
    assert edits.systematic == {"address": 4, "table": 4}
    assert edits.hand == 6
    score = compare("done", model, drafted, offset=-1, table="holding")
    assert (score.exact, score.proven, score.not_found) == (3, 5, ["alarm"])
    assert score.wrong_stated == ["current.scale: drafted 0.01, proven 0.001"]
    assert publicdocs.as_printed(score, drafted, model, -1, "holding") == 0  # every address moved
    # read at the printed addresses the draft matches shifted neighbours, not its own registers
    assert compare("done", model, drafted).exact_names != score.exact_names


def test_without_a_map_choice_a_table_written_is_a_hand_edit(tmp_path: Path) -> None:
    drafted = drafted_from(write_map(tmp_path / "draft.yaml", DRAFT[:2]))
    data, model = finished(write_map(tmp_path / "done.yaml", [reg("speed", 100, table="holding", scale=0.1, unit="Hz"),
                                                              reg("current", 101, scale=0.01, unit="A")]))
    edits = publicdocs.hand_edits(drafted, data, model)
    assert edits.fields == ["speed.table"] and not edits.systematic and edits.hand == 1
    with_choice = publicdocs.hand_edits(drafted, data, model, table="holding")
    assert with_choice.systematic == {"table": 1} and with_choice.hand == 0
    score = compare("done", model, drafted, table="holding")
    assert score.exact == 2 and publicdocs.as_printed(score, drafted, model, 0, "holding") == 2


def manifest(tmp_path: Path, documents: list[dict[str, Any]]) -> Path:
    path = tmp_path / "public_docs.json"
    path.write_text(json.dumps({"documents": documents}), encoding="utf-8")
    return path


def entry(file: str, sha: str, map_path: str | None) -> dict[str, Any]:
    return {"file": file, "title": file, "revision": "1", "format": "CSV", "sha256": sha, "size": 1,
            "draft_args": [], "map": map_path, "map_choices": {}}


def test_absent_or_different_documents_are_rows_not_numbers(tmp_path: Path) -> None:
    folder = tmp_path / "docs"
    folder.mkdir()
    (folder / "changed.csv").write_text("Address,Name\n1,A\n", encoding="utf-8")
    path = manifest(tmp_path, [entry("gone.pdf", "0" * 64, "maps/wattnode_wnc.yaml"),
                               entry("changed.csv", "1" * 64, "maps/wattnode_wnc.yaml")])
    section = publicdocs.run(folder=folder, manifest=path)
    absolute = {r.name: r.absolute for r in section.rows}
    assert absolute["gone.pdf"] == f"not measured: gone.pdf absent (looked in {folder})"
    assert absolute["changed.csv"] == "not measured: changed.csv sha256 differs from the manifest's"
    assert absolute["documents with a finished map measured"] == "0 of 2"
    assert all(r.ratio is None for r in section.rows) and section.error is None
    assert any("gone.pdf absent" in line for line in section.detail)


def test_a_document_finished_as_drafted_is_exact_with_no_hand_edits(tmp_path: Path) -> None:
    folder = tmp_path / "docs"
    folder.mkdir()
    doc = folder / "dev.csv"
    doc.write_text("Address,Name,Type,Scale,Unit,Access\n100,Speed,uint16,0.1,Hz,R\n101,Mode,uint16,1,,RW\n",
                   encoding="utf-8")
    done = tmp_path / "maps" / "dev.yaml"
    done.parent.mkdir()
    done.write_text(make_draft(doc, "dev").text, encoding="utf-8")
    sha = hashlib.sha256(doc.read_bytes()).hexdigest()
    section = publicdocs.run(folder=folder, manifest=manifest(tmp_path, [entry("dev.csv", sha, str(done))]))
    row = next(r for r in section.rows if r.name == "dev.csv: registers exact")
    assert row.ratio == 1.0 and "hand edits 0 (+0 map choices)" in row.absolute, row.absolute
    assert next(r for r in section.rows if r.name == "wrong fields written").met is True


def test_sunspec_comparison_lists_what_is_missed_and_why() -> None:
    import sunspecprobe

    def cell(name: str, **kw: Any) -> dict[str, Any]:
        return {"name": name, "register": name, "type": "u16", "words": 1, "scale register": None, "access": "r",
                "unit": None, "not available": (), "scale": 1.0, **kw}

    proven = {("holding", 212): cell("f_store"), ("holding", 40000): cell("marker"),
              ("holding", 40002): cell("w", **{"scale register": 40003}), ("holding", 40003): cell("w_sf", type="s16"),
              ("holding", 40004): cell("volts", access="r")}
    probed = {("holding", 40000): cell("marker"), ("holding", 40002): cell("w"),
              ("holding", 40003): cell("w_sf", type="s16"), ("holding", 40004): cell("volts", access="rw"),
              ("holding", 40009): cell("pad")}
    r = sunspecprobe.compare(proven, probed, 40000)
    assert (r["same"], r["sunspec"], r["registers_same"], r["registers"]) == (3, 4, 3, 5)
    assert r["outside"] == ["f_store"] and r["absent"] == [] and r["extra"] == ["pad"]
    assert r["differ"]["scale register"] == [("w", None, 40003)] and r["differ"]["access"] == [("volts", "rw", "r")]
    assert "probed 'rw', proven 'r': 1 (volts)" in sunspecprobe._pairs(r["differ"]["access"])

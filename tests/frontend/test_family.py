"""Device families: a map that `extends` another gives only what its model changes.

`drivemap new` shows a variant in a commented section; uncommented as written it validates. The
chain is resolved (cycles refused), every error points at the file that made it, and the generated
docs list what the variant changes."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import pytest

from drivemap.cli import main
from drivemap.compiler import compile_map

ROOT = Path(__file__).resolve().parents[2]


def run(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(list(argv))
    return code, out.getvalue(), err.getvalue()


@pytest.fixture
def family(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A project with `drivemap new acme` and the scaffold's commented variant saved as acme_xl.yaml."""
    monkeypatch.chdir(tmp_path)
    assert run("new", "acme")[0] == 0
    text = (tmp_path / "maps" / "acme.yaml").read_text(encoding="utf-8")
    section = text[text.index("# ---- A second model"):].splitlines()[3:]
    assert section and all(line.startswith("#") for line in section)
    (tmp_path / "maps" / "acme_xl.yaml").write_text(
        "\n".join(line[2:] if line.startswith("# ") else line[1:] for line in section) + "\n", encoding="utf-8")
    return tmp_path


def edit(path: Path, old: str, new: str) -> None:
    text = path.read_text(encoding="utf-8")
    assert text.count(old) == 1, old
    path.write_text(text.replace(old, new), encoding="utf-8")


def test_the_scaffolds_variant_validates_as_written(family: Path) -> None:
    code, out, err = run("validate")
    assert code == 0, err
    assert "maps/acme.yaml: ok" in out and "maps/acme_xl.yaml: ok" in out
    base, xl = compile_map("maps/acme.yaml"), compile_map("maps/acme_xl.yaml")
    assert xl.name == "acme_xl" and xl.variant is not None and xl.variant.extends == ("maps/acme.yaml",)
    names = {r.name for r in xl.registers}
    assert "heatsink_temperature" not in names and "motor_temperature" in names
    assert names - {"motor_temperature"} == {r.name for r in base.registers} - {"heatsink_temperature"}
    assert base.register("frequency_command").max == 400 and xl.register("frequency_command").max == 600
    assert xl.register("frequency_command").scale == base.register("frequency_command").scale
    assert [(c.register, c.kind, c.values) for c in xl.identity] == [
        ("model_code", "equals", (0x0C6B,)), ("model_name", "prefix", ("ACME",))]
    assert xl.examples == base.examples and xl.protocol == base.protocol


def test_docs_say_what_the_variant_changes(family: Path) -> None:
    assert run("build")[0] == 0
    doc = (family / "generated" / "docs" / "acme_xl.md").read_text(encoding="utf-8")
    section = doc[doc.index("### A variant of acme.yaml"):doc.index("### Identity")]
    assert "This map extends `acme.yaml` and changes:" in section
    for line in ("register heatsink\\_temperature: removed", "register frequency\\_command: max, source changed",
                 "register motor\\_temperature: added", "identity check model\\_code: replaced", "device.title: changed"):
        assert f"- {line}" in section, section
    assert "A variant of" not in (family / "generated" / "docs" / "acme.md").read_text(encoding="utf-8")


def test_a_model_id_and_a_chain_resolve(family: Path) -> None:
    edit(family / "maps" / "acme_xl.yaml", "extends: acme.yaml", "extends: acme")
    (family / "maps" / "acme_xxl.yaml").write_text(
        "drivemap: 2\nextends: acme_xl\ndevice: {model: acme_xxl, title: XXL}\n"
        "registers:\n  - {name: frequency_command, max: 650}\n", encoding="utf-8")
    xxl = compile_map("maps/acme_xxl.yaml")
    assert xxl.variant is not None and xxl.variant.extends == ("maps/acme_xl.yaml", "maps/acme.yaml")
    assert xxl.register("frequency_command").max == 650 and "motor_temperature" in {r.name for r in xxl.registers}


def test_every_error_points_at_the_file_that_made_it(family: Path) -> None:
    xl = family / "maps" / "acme_xl.yaml"
    edit(xl, "address: 0x0131", "address: 0x0130")
    code, _, err = run("validate", "maps/acme_xl.yaml")
    assert code == 1
    base_lines = (family / "maps" / "acme.yaml").read_text(encoding="utf-8").splitlines()
    named = next(i for i, text in enumerate(base_lines, 1) if "name: model_code" in text)
    line = next(i for i, text in enumerate(base_lines, 1) if i >= named and "address:" in text)
    assert err.splitlines()[:2] == [
        "maps/acme_xl.yaml:10:40: error: register 'motor_temperature' overlaps 'model_code' at address 0x0130",
        f"maps/acme.yaml:{line}:14: note: 'model_code' is defined here"]
    edit(xl, "address: 0x0130", "address: 0x0131")
    edit(family / "maps" / "acme.yaml", "    unit: Hz\n    min: 0\n", "    unit: Hz\n    min: fast\n")
    code, _, err = run("validate", "maps/acme_xl.yaml")
    assert code == 1 and err.startswith("maps/acme.yaml:") and "registers[1].min" in err


def test_cycles_and_missing_bases_are_refused(family: Path) -> None:
    xl = family / "maps" / "acme_xl.yaml"
    (family / "maps" / "loop.yaml").write_text("drivemap: 2\nextends: acme_xl.yaml\ndevice: {model: loop, title: L}\n",
                                               encoding="utf-8")
    edit(xl, "extends: acme.yaml", "extends: loop.yaml")
    code, _, err = run("validate", "maps/acme_xl.yaml")
    assert (code, err.splitlines()[0]) == (1, "maps/loop.yaml:2:10: error: extends makes a cycle: "
                                              "acme_xl.yaml -> loop.yaml -> acme_xl.yaml")
    edit(xl, "extends: loop.yaml", "extends: nowhere")
    code, _, err = run("validate", "maps/acme_xl.yaml")
    assert code == 1 and err.startswith("maps/acme_xl.yaml:2:10: error: extends 'nowhere': no map file maps/nowhere.yaml")


def test_remove_names_only_what_the_base_has(family: Path) -> None:
    edit(family / "maps" / "acme_xl.yaml", "registers: [heatsink_temperature]", "registers: [heatsink_temperature, fan]")
    code, _, err = run("validate", "maps/acme_xl.yaml")
    assert code == 1 and err.startswith("maps/acme_xl.yaml:12:37: error: remove: the base map has no register fan")


def test_removing_a_register_an_example_reads_is_an_error(family: Path) -> None:
    edit(family / "maps" / "acme_xl.yaml", "registers: [heatsink_temperature]", "registers: [line_voltage]")
    code, _, err = run("validate", "maps/acme_xl.yaml")
    assert code == 1 and "line_voltage" in err and "maps/acme.yaml:" in err


def test_protocol_items_merge_by_code_and_registers_keep_their_file(family: Path) -> None:
    from drivemap.device.target import load_target

    (family / "maps" / "acme_lite.yaml").write_text(
        "drivemap: 2\nextends: acme\ndevice: {model: acme_lite, title: Lite}\n"
        "protocol:\n"
        "  exceptions:\n    - {code: 0x03, meaning: Value out of range (Lite wording).}\n"
        "    - {code: 0x06, name: slave_busy, meaning: Busy., source: \"manual §2 (Lite)\"}\n"
        "  unit_ids: {min: 1, max: 31, source: \"manual §1 (Lite)\"}\n"
        "remove:\n  function_codes: [0x0F]\n", encoding="utf-8")
    base, lite = compile_map("maps/acme.yaml"), compile_map("maps/acme_lite.yaml")
    assert [e.code for e in lite.protocol.exceptions] == [0x01, 0x02, 0x03, 0x06]
    three = next(e for e in lite.protocol.exceptions if e.code == 0x03)
    assert three.meaning == "Value out of range (Lite wording)." and three.name == "illegal_data_value"
    assert 0x0F not in {f.code for f in lite.protocol.function_codes}
    assert (lite.protocol.unit_min, lite.protocol.unit_max) == (1, 31) != (base.protocol.unit_min, base.protocol.unit_max)
    assert lite.variant is not None and "function code 0x0F: removed" in lite.variant.changes
    assert "exception 0x03: meaning changed" in lite.variant.changes
    target = load_target("maps/acme_lite.yaml")
    where = target.where(lite.register("frequency_command"))
    assert where.startswith("maps/acme.yaml:")


def test_an_error_at_an_inherited_value_notes_the_override(family: Path) -> None:
    edit(family / "maps" / "acme_xl.yaml", "  - {name: frequency_command, max: 600,",
         "  - {name: run_state, type: f32, word_order: high_first, source: \"manual §3 (XL)\"}\n"
         "  - {name: frequency_command, max: 600,")
    code, _, err = run("validate", "maps/acme_xl.yaml")
    lines = err.splitlines()
    assert code == 1 and lines[0].startswith("maps/acme.yaml:") and "cannot have enum" in lines[0], err
    assert lines[1] == "maps/acme_xl.yaml:9:5: note: the item is overridden here (the value above is inherited from the base)"

"""Golden corpus of broken maps: each file's exact diagnostics, never a traceback.

Each case (``tests/bad_maps/<case>.patch`` against a base map, or a whole ``<case>.yaml``: see
:mod:`tests.badmaps`) has ``<case>.expected`` next to it holding what
``drivemap validate --exporter python --exporter docs`` prints on stderr: the front end's errors and
those of the checks of the exporters ``drivemap build`` runs. Plain ``drivemap validate`` (the front
end alone) prints the same for every case but :data:`EXPORTER_CASES`. Regenerate after a deliberate message change with
``DRIVEMAP_UPDATE_GOLDENS=1 pytest tests/frontend/test_bad_maps.py`` and review the diff.
"""

from __future__ import annotations

import contextlib
import io
import os
import resource
import subprocess
import sys
from pathlib import Path

import pytest

from drivemap.cli import main
from drivemap.frontend.load import MAX_MAP_BYTES
from tests.badmaps import CORPUS, ROOT, case_names, case_text, materialize

CASES = case_names()


#: The cases only an exporter's check refuses (generated Python names, docs anchors and file names).
EXPORTER_CASES = frozenset({
    "bit_named_int_in_record", "bit_names_if_and_if_underscore", "duplicate_group_name", "enum_member_looks_unknown",
    "enum_name_taken_by_client", "enum_named_any", "enum_named_command", "enum_named_field", "enum_named_none",
    "enum_named_readwrite", "enum_names_differ_only_in_case", "exception_class_equals_enum",
    "exception_classes_collide", "flags_name_intcodec", "group_title_is_a_section", "index",
    "register_name_clashes_client", "register_named_float", "register_named_tuple",
})
BUILD_CHECKS = ("--exporter", "python", "--exporter", "docs")


def run_validate(path: Path | str, *flags: str) -> tuple[int, str, str]:
    """``drivemap validate`` of ``path`` (shown relative to the cases' tree, where the tests stand)."""
    shown = os.path.relpath(path) if isinstance(path, Path) else path
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["validate", *flags, shown])
    return code, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def tree(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The cases written out as the files ``drivemap validate`` reads (``tests/bad_maps/<case>.yaml``)."""
    return materialize(tmp_path_factory.mktemp("bad_maps_tree"))


@pytest.fixture(autouse=True)
def _at_root(monkeypatch: pytest.MonkeyPatch, tree: Path) -> None:
    monkeypatch.chdir(tree)


def test_corpus_is_large_enough() -> None:
    assert len(CASES) >= 40


@pytest.mark.parametrize("case", CASES)
def test_bad_map_diagnostic(case: str) -> None:
    code, out, err = run_validate(f"tests/bad_maps/{case}.yaml", *BUILD_CHECKS)
    golden = CORPUS / f"{case}.expected"
    if os.environ.get("DRIVEMAP_UPDATE_GOLDENS"):
        golden.write_text(err, encoding="utf-8")
    assert code == 1
    assert out == ""
    assert "Traceback" not in err
    assert err == golden.read_text(encoding="utf-8")
    first = err.splitlines()[0]
    assert first.startswith(f"tests/bad_maps/{case}.yaml:"), first
    assert ": error: " in first


@pytest.mark.parametrize("case", CASES)
def test_plain_validate_is_the_front_end(case: str) -> None:
    """Without ``--exporter`` the exporters' checks do not run: the golden output but for their errors."""
    code, out, err = run_validate(f"tests/bad_maps/{case}.yaml")
    golden = (CORPUS / f"{case}.expected").read_text(encoding="utf-8")
    if case not in EXPORTER_CASES:
        assert (code, out, err) == (1, "", golden)
        return
    errors = [line for line in err.splitlines() if ": error: " in line]
    assert all(line in golden.splitlines() for line in errors)
    assert len(errors) < golden.count(": error: ")
    assert code == (1 if errors else 0)


def _limited() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (1 << 30, 1 << 30))


@pytest.mark.parametrize("case", ["alias_bomb", "deep_nesting", "python_object_tag", "huge_integer"])
def test_hostile_input_in_a_subprocess(case: str, tree: Path) -> None:
    """The real command, bounded to 1 GiB of memory and 60 s: exit 1, one located message."""
    proc = subprocess.run(
        [sys.executable, "-m", "drivemap.cli", "validate", f"tests/bad_maps/{case}.yaml"],
        cwd=tree, capture_output=True, text=True, timeout=60, preexec_fn=_limited,
    )
    assert proc.returncode == 1
    assert "Traceback" not in proc.stderr
    assert proc.stderr.startswith(f"tests/bad_maps/{case}.yaml:")


def test_fifty_megabyte_map_is_refused(tmp_path: Path) -> None:
    big = tmp_path / "huge.yaml"
    with open(big, "w", encoding="utf-8") as handle:
        line = "# " + "x" * 1021 + "\n"
        for _ in range(50 * 1024):
            handle.write(line)
    assert big.stat().st_size >= 50 * 1024 * 1024 > MAX_MAP_BYTES
    proc = subprocess.run(
        [sys.executable, "-m", "drivemap.cli", "validate", str(big)],
        cwd=ROOT, capture_output=True, text=True, timeout=60, preexec_fn=_limited,
    )
    assert proc.returncode == 1
    assert proc.stderr.splitlines()[0] == f"{big}:1:1: error: file larger than {MAX_MAP_BYTES} bytes; refused"


def test_all_errors_of_a_file_in_one_run(tmp_path: Path) -> None:
    text = case_text("overlapping_registers")
    text = text.replace("    access: ro\n", "    access: ro\n").replace("  - name: run_state\n", "  - name: class\n")
    bad = tmp_path / "overlapping_registers.yaml"
    bad.write_text(text, encoding="utf-8")
    code, _, err = run_validate(bad)
    assert code == 1
    assert "is a Python keyword" in err and "overlaps" in err


def test_missing_file() -> None:
    code, _, err = run_validate("maps/no_such_map.yaml")
    assert code == 1
    assert err.startswith("maps/no_such_map.yaml:1:1: error: cannot read file")


@pytest.mark.parametrize("text", [
    "[" * 1_000_000,
    "a: " + "{x: " * 25_000 + "1" + "}" * 25_000,
    "a:\n" + "".join("  " * i + "- \n" for i in range(1, 60)),
], ids=["flow-1M", "mapping-25k", "block-60"])  # explicit ids: pytest 8.0 puts the whole text in the id (and the env)
def test_deep_nesting_is_refused_before_anything_recurses(tmp_path: Path, text: str) -> None:
    """25,000- and 1,000,000-deep documents end in one located error, quickly (no crash, no hang)."""
    deep = tmp_path / "deep.yaml"
    deep.write_text(text, encoding="utf-8")
    proc = subprocess.run([sys.executable, "-m", "drivemap.cli", "validate", str(deep)], cwd=ROOT,
                          capture_output=True, text=True, timeout=60, preexec_fn=_limited)
    assert proc.returncode == 1
    assert "nesting deeper than 40 levels" in proc.stderr.splitlines()[0]
    assert proc.stderr.startswith(f"{deep}:")


def test_special_files_are_refused_without_reading(tmp_path: Path) -> None:
    fifo = tmp_path / "fifo.yaml"
    os.mkfifo(fifo)
    zero = tmp_path / "zero.yaml"
    zero.symlink_to("/dev/zero")
    for path in (fifo, zero, tmp_path):
        proc = subprocess.run([sys.executable, "-m", "drivemap.cli", "validate", str(path)], cwd=ROOT,
                              capture_output=True, text=True, timeout=30, preexec_fn=_limited)
        assert proc.returncode == 1, path
        if path != tmp_path:
            assert proc.stderr.splitlines()[0] == f"{path}:1:1: error: not a regular file (a FIFO, device or folder); refused"


def test_a_large_realistic_map_is_not_refused_for_its_size(tmp_path: Path) -> None:
    """The one size limit admits an 11 MB map (the size of 60,000 registers)."""
    from drivemap.frontend.load import load_file

    text = case_text("huge_integer").replace("123456789012345678901234567890", "0x0101")
    big = tmp_path / "big.yaml"
    big.write_text(text + ("#" + "x" * 99 + "\n") * 110_000, encoding="utf-8")
    assert 11_000_000 < big.stat().st_size < MAX_MAP_BYTES
    assert load_file(big).data["device"]["model"] == "huge_integer"


def test_depth_message_is_ours_whatever_libyaml_says(monkeypatch: pytest.MonkeyPatch) -> None:
    """libyaml's own nesting limit (and its wording) changes between releases; when the fast parser
    gives up, the depth check still decides, with its own located message."""
    import yaml

    from drivemap.diagnostics import CompileError
    from drivemap.frontend import load

    real_parse = yaml.parse

    def libyaml_refusing(text: str, Loader: type = yaml.SafeLoader) -> object:  # noqa: N803
        if Loader is not yaml.SafeLoader:
            raise yaml.YAMLError("maximum nesting depth exceeded")
        return real_parse(text, Loader=Loader)

    monkeypatch.setattr(yaml, "CSafeLoader", type("Fake", (), {}), raising=False)
    monkeypatch.setattr(yaml, "parse", libyaml_refusing)
    with pytest.raises(CompileError) as caught:
        load.load_text("a: " + "[" * 5000 + "]" * 5000, "deep.yaml")
    assert caught.value.diagnostics[0].format().startswith("deep.yaml:")
    assert "nesting deeper than 40 levels" in caught.value.diagnostics[0].message


def test_every_patch_applies_to_its_base_and_changes_it() -> None:
    """A patch applies line for line (a changed base fails here, naming the case), and each case differs
    from the base it is made from: a case is its change, nothing else."""
    from tests.badmaps import apply

    patches = sorted(CORPUS.glob("*.patch"))
    assert len(patches) > 100
    for patch in patches:
        text = patch.read_text(encoding="utf-8")
        base = (CORPUS / text.splitlines()[0][4:].strip()).read_text(encoding="utf-8")
        assert apply(base, text, patch.stem) != base.replace("{case}", patch.stem), patch.name


def test_a_patch_that_no_longer_applies_is_an_error() -> None:
    from tests.badmaps import PatchError, apply

    base = (CORPUS / "_bases" / "scaffold.yaml").read_text(encoding="utf-8")
    patch = "--- _bases/scaffold.yaml\n+++ x.yaml\n@@ -5,1 +5,1 @@\n-not this line\n+x\n"
    with pytest.raises(PatchError, match="line 5 of the base"):
        apply(base, patch, "x")

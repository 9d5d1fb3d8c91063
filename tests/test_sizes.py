"""Hand-written code stays in units a person reads whole: no module over 500 lines, no function over 60
(generated code, under ``generated/`` and kept as test fixtures under ``tests/fixtures/``, is the compiler's
and not counted)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
FOLDERS = ("generator/drivemap", "bench", "tests", ".ci")
MAX_MODULE_LINES = 500
MAX_FUNCTION_LINES = 60


def _modules() -> list[Path]:
    return sorted(p for folder in FOLDERS for p in (ROOT / folder).rglob("*.py")
                  if ".venv" not in p.parts and "__pycache__" not in p.parts
                  and not p.is_relative_to(ROOT / "tests" / "fixtures"))


def test_there_is_code_to_measure() -> None:
    assert len(_modules()) > 300


@pytest.mark.parametrize("folder", FOLDERS)
def test_no_module_over_500_lines(folder: str) -> None:
    long = {str(p.relative_to(ROOT)): n for p in _modules() if p.is_relative_to(ROOT / folder)
            and (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_MODULE_LINES}
    assert long == {}


@pytest.mark.parametrize("folder", FOLDERS)
def test_no_function_over_60_lines(folder: str) -> None:
    long = {}
    for path in _modules():
        if not path.is_relative_to(ROOT / folder):
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                lines = (node.end_lineno or node.lineno) - node.lineno + 1
                if lines > MAX_FUNCTION_LINES:
                    long[f"{path.relative_to(ROOT)}:{node.lineno} {node.name}"] = lines
    assert long == {}

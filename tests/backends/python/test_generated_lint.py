"""Generated spec modules import only the spec classes they use, also for a map that documents no
exception codes (the WattNode register list names none): ruff's F401 would fail the generated code."""
import subprocess
import sys
from pathlib import Path

from drivemap.backends.exporters.base import Options
from drivemap.backends.views.spec import context
from drivemap.compiler import compile_map

ROOT = Path(__file__).resolve().parents[3]


def _imports(model: object) -> list[str]:
    return list(context(model, Options())["imports"])  # type: ignore[arg-type]


def test_no_exception_spec_import_without_exceptions() -> None:
    model = compile_map(ROOT / "maps" / "wattnode_wnc.yaml")
    assert model.protocol.exceptions == ()
    assert "ExceptionSpec" not in _imports(model)
    withex = compile_map(ROOT / "maps" / "solax_x1x3_g4.yaml")
    assert withex.protocol.exceptions and "ExceptionSpec" in _imports(withex)


def test_committed_spec_of_a_map_without_exceptions_is_ruff_clean() -> None:
    spec = ROOT / "generated" / "drivemap_models" / "wattnode_wnc" / "spec.py"
    ruff = subprocess.run([sys.executable, "-m", "ruff", "check", "--no-cache", str(spec)],
                          capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert ruff.returncode == 0, ruff.stdout + ruff.stderr

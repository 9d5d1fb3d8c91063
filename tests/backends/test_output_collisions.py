"""Outputs that would collide are located errors before anything is written."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.frontend.test_project import ok, project, run, snapshot

__all__ = ["project"]  # the fixture

HEAD = '[tool.drivemap]\nout = "generated"\n'


def _export(output: str, model: str = "acme", fmt: str = "json") -> str:
    return f'\n[[tool.drivemap.exports]]\nformat = "{fmt}"\nmodel = "{model}"\noutput = "{output}"\n'


@pytest.mark.parametrize(("exports", "line", "message"), [
    (_export("generated/acme/client.py"), 4, "exports: output generated/acme/client.py is also written by "
                                              "drivemap build's own output"),
    (_export("out/acme.json") + _export("out/acme.json", fmt="csv"), 9,
     "exports: output out/acme.json is also written by the export at line 4"),
    (_export("maps/acme.json"), 4, "exports: output maps/acme.json is inside the maps folder"),
    (_export("../elsewhere/acme.json"), 4, "is outside the project (exports write inside it)"),
    (_export("maps/acme.yaml", fmt="csv"), 4, "is inside the maps folder"),
])
def test_colliding_exports_are_located_errors(project: Path, exports: str, line: int, message: str) -> None:
    ok("new", "acme")
    ok("build")
    (project / "pyproject.toml").write_text(HEAD + exports, "utf-8")
    before = snapshot(project.parent)
    for verb in ("build", "check"):
        code, _, err = run(verb)
        assert code == 1, verb
        assert err.startswith(f"pyproject.toml:{line}:1: error: "), err
        assert message in err
    assert snapshot(project.parent) == before


def test_two_maps_with_one_model_id_are_an_error(project: Path) -> None:
    ok("new", "acme")
    (project / "more").mkdir()
    (project / "more" / "acme.yaml").write_text((project / "maps" / "acme.yaml").read_text("utf-8"), "utf-8")
    (project / "pyproject.toml").write_text('[tool.drivemap]\nmaps = ["maps", "more"]\n', "utf-8")
    code, _, err = run("build")
    assert code == 1
    assert "more/acme.yaml:" in err and "model id 'acme' is also the id of maps/acme.yaml" in err
    assert not (project / "generated").exists()

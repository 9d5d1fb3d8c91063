"""Print requirements pinning every direct dependency to the lowest version pyproject.toml allows.

pip has no "lowest" resolution; pinning each ``name>=X`` requirement (of the dependencies and of
the extras named on the command line) to ``name==X`` gives the direct-dependency set of ``uv pip
install --resolution lowest-direct``. Requirements without a lower bound are printed as written.
``--skip a,b`` leaves requirements out (amqtt, which pins PyYAML>=6.0.2 for itself); ``--free a,b``
keeps them as written, unpinned (the linters the tests run: their newest release judges the code).

    pip install -e . -r <(python .ci/lowest_constraints.py test --skip amqtt,import-linter --free mypy,ruff)
"""

from __future__ import annotations

import argparse
import re
import tomllib
from pathlib import Path

parser = argparse.ArgumentParser()
parser.add_argument("extras", nargs="*")
parser.add_argument("--skip", default="")
parser.add_argument("--free", default="")
args = parser.parse_args()
skip = {name.strip().lower() for name in args.skip.split(",") if name.strip()}
free = {name.strip().lower() for name in args.free.split(",") if name.strip()}
pyproject = Path(__file__).resolve().parent.parent / "pyproject.toml"
project = tomllib.loads(pyproject.read_text(encoding="utf-8"))["project"]
requirements = list(project["dependencies"])
for extra in args.extras:
    requirements += project["optional-dependencies"][extra]
seen: set[str] = set()
for requirement in requirements:
    match = re.fullmatch(r"\s*([A-Za-z0-9_.-]+)(\[[^\]]*\])?\s*([^;]*?)\s*(;.*)?", requirement)
    if match is None:
        raise SystemExit(f"cannot read requirement {requirement!r}")
    name, extras, spec, _ = match.groups()
    if name.lower() in skip or name.lower() in seen:
        continue
    seen.add(name.lower())
    lower = re.search(r">=\s*([0-9][^,\s]*)", spec or "")
    print(f"{name}{extras or ''}=={lower.group(1)}" if lower and name.lower() not in free else requirement)

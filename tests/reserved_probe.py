"""The names and files generated code already uses, read from what the templates really produce.

Not a hand list: a probe map (``drivemap new``'s scaffold plus a flags register, so that every kind
of register and every optional import appears) is rendered by the built-in exporters and the
result is read back:

* ``module``: every name bound at module level of the generated ``client.py`` and ``__init__.py``
  (imports, classes, constants) except those the probe map itself gave (its enums, bit-field
  classes, exception classes, codecs), plus everything exported by the modules they import names
  from (a map feature the probe lacks may make the template import another name of them);
* ``annotation``: builtins named in the annotations inside the generated classes (``int``,
  ``float``, ``tuple`` ...): a register or bit field of that name would shadow them there;
* ``client``: every attribute of a generated client (what its classes and the runtime bases define,
  what their methods assign to ``self``) except the probe's registers;
* ``outputs``: per exporter, the files of one model (``{model}`` for its id) and the files written
  once for all models (``index.md``, ``__init__.py``, ``py.typed``);
* ``headings``: the anchors of the fixed headings of a model's docs page.

Computed once per process (a few tens of milliseconds).
"""

from __future__ import annotations

import ast
import builtins
import importlib
import re
import sys
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

__all__ = ["PROBE", "Reserved", "module_text", "reserved"]

PROBE = "drivemap_probe_map"


@dataclass(frozen=True)
class Reserved:
    module: frozenset[str]
    annotation: frozenset[str]
    client: frozenset[str]
    outputs: tuple[tuple[str, frozenset[str], frozenset[str]], ...]
    """(exporter, files of one model with ``{model}`` for its id, files written once for all models)"""
    headings: frozenset[str]


def _probe() -> Any:
    """The probe model: the scaffold map, with a register of single-bit flags added."""
    from drivemap.backends.render import scaffold
    from drivemap.frontend.load import load_text
    from drivemap.model.build import build_model
    from drivemap.model.nodes import Status

    doc = load_text(scaffold(PROBE), f"{PROBE}.yaml")
    data = doc.data
    data["registers"].append({
        "name": "probe_flags", "address": 0x0F00, "group": data["registers"][0]["group"], "access": "rw",
        "bits": [{"name": "FIRST", "offset": 0, "label": "first"}, {"name": "SECOND", "offset": 1, "label": "second"}],
        "source": "probe",
    })
    statuses: dict[str, Status] = {e["name"]: "verified" for e in data["examples"]}
    return build_model(f"{PROBE}.yaml", data, statuses, {})


def _bound(tree: ast.Module) -> tuple[set[str], set[str]]:
    """(names bound at module level, modules names are imported from)."""
    names: set[str] = set()
    sources: set[str] = set()
    for node in tree.body:
        if isinstance(node, ast.ImportFrom):
            names.update(a.asname or a.name for a in node.names)
            if node.module and not node.level:
                sources.add(node.module)
        elif isinstance(node, ast.Import):
            names.update((a.asname or a.name).split(".")[0] for a in node.names)
        elif isinstance(node, (ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            names.add(node.name)
        elif isinstance(node, ast.Assign):
            names.update(t.id for t in node.targets if isinstance(t, ast.Name))
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            names.add(node.target.id)
    return names, sources


def _annotation_builtins(tree: ast.Module) -> set[str]:
    found: set[str] = set()
    for cls in (n for n in ast.walk(tree) if isinstance(n, ast.ClassDef)):
        for node in ast.walk(cls):
            notes: list[ast.expr] = []
            if isinstance(node, ast.AnnAssign):
                notes.append(node.annotation)
            elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                args = node.args
                notes += [a.annotation for a in (*args.posonlyargs, *args.args, *args.kwonlyargs) if a.annotation]
                if node.returns is not None:
                    notes.append(node.returns)
            for note in notes:
                found.update(n.id for n in ast.walk(note) if isinstance(n, ast.Name) and hasattr(builtins, n.id))
    return found


def _self_attributes(tree: ast.AST) -> set[str]:
    """Names assigned as ``self.NAME`` or ``cls.NAME`` anywhere in ``tree``."""
    return {t.attr for n in ast.walk(tree) if isinstance(n, (ast.Assign, ast.AnnAssign))
            for t in (n.targets if isinstance(n, ast.Assign) else [n.target])
            if isinstance(t, ast.Attribute) and isinstance(t.value, ast.Name) and t.value.id in ("self", "cls")}


def _client_attributes(client_tree: ast.Module) -> set[str]:
    """Attributes of generated client objects: what their classes and bases define, and what their
    ``__init__`` and the runtime's methods assign to ``self`` or ``cls``."""
    from pathlib import Path

    from drivemap.runtime.client.api import sync_client as runtime

    names: set[str] = set()
    modules: dict[str, dict[str, ast.ClassDef]] = {}  # runtime module -> its classes (the bases live in several)
    for base in (runtime.ClientBase, runtime.AsyncClientBase):
        names.update(dir(base))
        for cls in base.__mro__:
            module = sys.modules.get(cls.__module__)
            if module is None or not cls.__module__.startswith("drivemap.runtime.") or module.__file__ is None:
                continue
            classes = modules.get(cls.__module__)
            if classes is None:
                source = ast.parse(Path(module.__file__).read_text(encoding="utf-8"))
                classes = modules[cls.__module__] = {n.name: n for n in source.body if isinstance(n, ast.ClassDef)}
            if cls.__name__ in classes:
                names |= _self_attributes(classes[cls.__name__])
    for generated in (n for n in client_tree.body if isinstance(n, ast.ClassDef) and n.name.endswith("Client")):
        names |= _self_attributes(generated)
        for node in generated.body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                names.add(node.name)
            elif isinstance(node, ast.Assign):
                names.update(t.id for t in node.targets if isinstance(t, ast.Name))
    return names


def _fixed_headings() -> frozenset[str]:
    from drivemap.backends.render import TEMPLATES
    from drivemap.vocab.escape import slug

    text = (TEMPLATES / "model.md.jinja").read_text(encoding="utf-8")
    return frozenset(slug(line.lstrip("#")) for line in text.splitlines()
                     if re.match(r"#{1,6} ", line) and "{{" not in line and "{%" not in line)


def _outputs(model: Any) -> tuple[tuple[str, frozenset[str], frozenset[str]], ...]:
    from drivemap.backends.exporters import BUILTIN, available
    from drivemap.backends.exporters.base import Options

    out = []
    for name, exporter_cls in available().items():
        if name not in BUILTIN:
            continue
        exporter = exporter_cls()
        per_model = {re.sub(rf"^{PROBE}(?=[/.]|$)", "{model}", rel) for rel in exporter.render(model, Options())}
        once = frozenset(exporter.render_collection([model], Options()))
        out.append((name, frozenset(per_model), once))
    return tuple(out)


@lru_cache(maxsize=1)
def reserved() -> Reserved:
    from drivemap.backends.exporters.python import PythonExporter
    from drivemap.backends.python.names import exception_classes

    model = _probe()
    files = PythonExporter().render(model, _options())
    client_tree = ast.parse(files[f"{PROBE}/client.py"])
    module, sources = _bound(client_tree)
    init_names, init_sources = _bound(ast.parse(files[f"{PROBE}/__init__.py"]))
    module |= init_names
    for source in sources | init_sources:
        if source.split(".")[0] == "drivemap":  # what a map feature the probe lacks may import too
            module.update(getattr(importlib.import_module(source), "__all__", ()))
    own = {e.name for e in model.enums} | {r.bits_class for r in model.registers if r.bits_class}
    own |= set(exception_classes([(e.name, e.code) for e in model.protocol.exceptions]))
    module = {n for n in module if n not in own and not n.startswith("_codec_")}
    client = _client_attributes(client_tree) - {r.name for r in model.registers}
    return Reserved(
        module=frozenset(module),
        annotation=frozenset(_annotation_builtins(client_tree)),
        client=frozenset(n for n in client if not n.startswith("__")),
        outputs=_outputs(model),
        headings=_fixed_headings(),
    )


def _options() -> Any:
    from drivemap.backends.exporters.base import Options

    return Options()


def _frozenset_text(items: frozenset[str], indent: str = "    ") -> str:
    lines, cur = [], ""
    for item in sorted(items):
        piece = repr(item) + ", "
        if len(cur) + len(piece) > 104:
            lines.append(cur.rstrip())
            cur = ""
        cur += piece
    if cur:
        lines.append(cur.rstrip())
    return "frozenset({\n" + "".join(f"{indent}    {line}\n" for line in lines) + indent + "})"


def module_text(found: Reserved) -> str:
    """The text of ``drivemap/vocab/reserved.py`` holding ``found`` (``python tests/reserved_probe.py``)."""
    outputs = "".join(f"        ({name!r}, {_frozenset_text(per, '        ')}, {_frozenset_text(once, '        ')}),\n"
                      for name, per, once in found.outputs)
    return f'''"""The names and files generated outputs already use: data the python (and docs) back end owns.

A map name equal to one of these would shadow or overwrite something the generated package or the
docs page defines; :mod:`.namecheck` refuses it. The sets are data, not computed at validation time:
``tests/vocab/test_generated_names.py`` renders a probe map through the built-in exporters, reads the output
back (``tests/reserved_probe.py``) and fails when these sets differ from what the templates really
produce. After a template or runtime change, ``python tests/reserved_probe.py > {_TARGET}``
writes this file anew.

* ``module``: every name bound at module level of a generated ``client.py`` / ``__init__.py``
  (imports, classes, constants) besides the map's own classes;
* ``annotation``: builtins named in annotations inside the generated classes;
* ``client``: every attribute of a generated client besides its registers;
* ``outputs``: per built-in exporter, the files of one model (``{{model}}`` for its id) and the files
  written once for all models;
* ``headings``: the anchors of the fixed headings of a model's docs page.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["RESERVED", "Reserved", "reserved"]


@dataclass(frozen=True)
class Reserved:
    module: frozenset[str]
    annotation: frozenset[str]
    client: frozenset[str]
    outputs: tuple[tuple[str, frozenset[str], frozenset[str]], ...]
    """(exporter, files of one model with ``{{model}}`` for its id, files written once for all models)"""
    headings: frozenset[str]


RESERVED = Reserved(
    module={_frozenset_text(found.module)},
    annotation={_frozenset_text(found.annotation)},
    client={_frozenset_text(found.client)},
    outputs=(
{outputs}    ),
    headings={_frozenset_text(found.headings)},
)


def reserved() -> Reserved:
    """The reserved names and files (:data:`RESERVED`)."""
    return RESERVED
'''


_TARGET = "generator/drivemap/vocab/reserved.py"

if __name__ == "__main__":
    sys.stdout.write(module_text(reserved()))

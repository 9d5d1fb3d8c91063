"""One escaping path for map text (map text never becomes code or markup), proven over all of Unicode, lone surrogates included.

Property tests (hypothesis) on :mod:`drivemap.vocab.escape`, whose functions are the templates' ``py``,
``doc``, ``md`` and ``mdcomment`` filters:

* a Python literal evaluates back to the text; a docstring body, in the contexts the templates put
  it, evaluates back to the text, stays on one line and cannot close the docstring (a label ending
  in ``"``);
* Markdown text is one line, UTF-8, and renders (markdown-it, CommonMark + tables) as exactly one
  table cell / heading / paragraph whose text is the map text with line breaks as spaces and
  unstorable characters as U+FFFD, with no markup at all;

and end to end: a map whose title is a lone surrogate (``"\\ud800"``) and whose labels end in
``"`` or carry every line separator builds with ``drivemap build`` (exit 0, no temporary files
left), imports, round-trips its texts in Python and adds no heading or table row to the docs.
"""

from __future__ import annotations

import ast
import contextlib
import importlib
import io
import sys
from pathlib import Path
from typing import Any

import pytest
import yaml
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from markdown_it import MarkdownIt

from drivemap.vocab.escape import LINE_BREAKS, md_comment, md_text, py_docstring, py_literal

ROOT = Path(__file__).resolve().parents[2]

EVERY_CHARACTER = st.characters(exclude_categories=())  # lone surrogates included
TRICKY = list(LINE_BREAKS) + ['"', "'", '"""', "\\", "\ud800", "\udfff", "|", "*", "_", "`", "<", ">", "&",
                              "[", "]", "~", "#", "-", "!", "\t", " ", "\x00", "\x7f", "\u00a0", "{{", "}}", "a"]
TEXTS = st.one_of(st.text(EVERY_CHARACTER), st.lists(st.sampled_from(TRICKY)).map("".join),
                  st.lists(st.one_of(st.sampled_from(TRICKY), EVERY_CHARACTER)).map("".join))
SETTINGS = settings(max_examples=1500, deadline=None, suppress_health_check=[HealthCheck.too_slow])
MD = MarkdownIt("commonmark").enable("table")


def shown(text: str) -> str:
    """What Markdown shows for ``text``: line breaks as spaces, what UTF-8 cannot hold (and NUL) as U+FFFD,
    no whitespace at either end."""
    out = "".join(" " if c in LINE_BREAKS else "\ufffd" if c == "\x00" or 0xD800 <= ord(c) <= 0xDFFF else c
                  for c in text)
    return out.strip()


def inline_text(children: list[Any]) -> tuple[str, set[str]]:
    """The text of an inline token's children and the kinds of the other tokens among them."""
    text = []
    kinds = set()
    for child in children:
        if child.type in ("text", "text_special"):
            text.append(child.content)
        else:
            kinds.add(child.type)
    return "".join(text), kinds


# ----------------------------------------------------------------------------- Python
@SETTINGS
@given(TEXTS)
@example('Stop "S"')
@example('"""')
@example("\\")
@example("\ud800")
def test_python_literal_round_trips(text: str) -> None:
    literal = py_literal(text)
    assert ast.literal_eval(literal) == text
    assert len(literal.splitlines()) == 1
    literal.encode("utf-8")


@SETTINGS
@given(TEXTS)
@example('Stop "S"')
@example('ends in a quote"')
@example('""""""')
@example("\u2028\u2029\x0b\x0c\x1c\x1d\x1e\x85")
def test_docstring_round_trips_on_one_line(text: str) -> None:
    body = py_docstring(text)
    assert len(body.splitlines()) <= 1
    body.encode("utf-8")
    want = as_docstring(text)
    assert ast.literal_eval('"""' + body + '"""') == want  # alone (an enum member's label)
    assert ast.literal_eval('"""Exception 0x01 ' + body + ": " + body + '."""') == f"Exception 0x01 {want}: {want}."
    assert ast.literal_eval('"""' + body + '""" """' + body + '"""') == want + want
    module = f'"""{body}"""\n\n\nclass C:\n    """{body}"""\n\n    X = 1\n    """{body}"""\n'
    tree = ast.parse(module)
    assert ast.get_docstring(tree, clean=False) == want
    cls = tree.body[1]
    assert isinstance(cls, ast.ClassDef) and ast.get_docstring(cls, clean=False) == want
    namespace: dict[str, Any] = {}
    exec(compile(tree, "<docstring>", "exec"), namespace)  # a class can hold it (no lone surrogate)
    assert namespace["C"].__doc__ == want


def as_docstring(text: str) -> str:
    """What a docstring shows for ``text``: the text, a lone surrogate as its ``\\uXXXX`` escape."""
    return "".join(f"\\u{ord(c):04x}" if 0xD800 <= ord(c) <= 0xDFFF else c for c in text)


# ----------------------------------------------------------------------------- Markdown
@SETTINGS
@given(TEXTS)
@example("| a | b |\n|---|---|\n| injected | row |")
@example("line\u2028# heading\u2029## another\x0b### third\x85#### fourth")
@example("*em* _em_ `code` [link](x) <b>bold</b> ~~strike~~ &amp; \\*")
@example("\ud800")
def test_markdown_text_is_one_cell_of_plain_text(text: str) -> None:
    cell = md_text(text)
    cell.encode("utf-8")
    assert len(cell.splitlines()) <= 1
    tokens = MD.parse(f"| a | b |\n|---|---|\n| x | {cell} |\n")
    rows = [t for t in tokens if t.type == "tr_open"]
    cells = [t for t in tokens if t.type == "td_open"]
    assert len(rows) == 2 and len(cells) == 2, "a map text added a row or a column"
    inline = [t for t in tokens if t.type == "inline"][-1]
    got, kinds = inline_text(inline.children or [])
    assert not kinds, f"markup from map text: {kinds}"
    assert got == shown(text), (got, shown(text))


@SETTINGS
@given(TEXTS)
@example("title\u2028# injected heading")
def test_markdown_heading_and_paragraph_stay_one_block(text: str) -> None:
    cell = md_text(text)
    heading = MD.parse(f"### {cell}\n\nafter\n")
    assert [t.type for t in heading if t.type.endswith("_open")] == ["heading_open", "paragraph_open"]
    got, kinds = inline_text(heading[1].children or [])
    assert not kinds and got == shown(text)
    para = MD.parse(f"**Notes:** {cell}\n")
    assert [t.type for t in para if t.type.endswith("_open")] == ["paragraph_open"]
    _, kinds = inline_text(para[1].children or [])
    assert kinds <= {"strong_open", "strong_close"}  # only the template's own bold


@SETTINGS
@given(TEXTS)
def test_markdown_comment_stays_a_comment(text: str) -> None:
    inner = md_comment(text)
    inner.encode("utf-8")
    assert "--" not in inner and len(inner.splitlines()) <= 1
    tokens = MD.parse(f"<!-- {inner} -->\n\nafter\n")
    assert [t.type for t in tokens][0] == "html_block" and tokens[0].content.count("-->") == 1


def test_none_is_a_dash() -> None:
    assert md_text(None) == "—"


# ----------------------------------------------------------------------------- end to end
HOSTILE = {
    "title": "\ud800",
    "label_quote": 'Stop "S"',
    "separators": "a\u2028# injected heading\u2029## another\x0b| x | y |\x0c\x1c\x1d\x1e\x85end\"",
}


def hostile_map() -> dict[str, Any]:
    from drivemap.backends.render import scaffold

    data: dict[str, Any] = yaml.safe_load(scaffold("hostile_text"))
    data["device"]["title"] = HOSTILE["title"]
    data["enums"]["RunState"]["values"][0]["label"] = HOSTILE["label_quote"]
    data["enums"]["RunState"]["values"][1]["label"] = HOSTILE["separators"]
    data["registers"][0]["bits"][0]["label"] = HOSTILE["label_quote"]
    data["registers"][0]["bits"][1]["label"] = HOSTILE["separators"]
    data["registers"][1]["notes"] = HOSTILE["separators"]
    data["groups"][0]["title"] = 'Command data "quoted"'
    data["protocol"]["exceptions"][0]["meaning"] = HOSTILE["label_quote"]
    return data


@pytest.fixture
def built(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    from drivemap.cli import main

    (tmp_path / "maps").mkdir()
    text = yaml.safe_dump(hostile_map(), allow_unicode=True, sort_keys=False)
    (tmp_path / "maps" / "hostile_text.yaml").write_text(text, encoding="utf-8", errors="surrogatepass")
    (tmp_path / "pyproject.toml").write_text('[tool.drivemap]\nmaps = "maps"\nout = "out/hostile_pkg"\n'
                                             'package = "hostile_pkg"\ndocs = "out/docs"\n', encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = main(["build"])
    assert code == 0, err.getvalue()
    assert not [p for p in tmp_path.rglob("*") if ".drivemap-tmp-" in p.name or p.name.startswith(".tmp-")]
    return tmp_path


def test_hostile_text_builds_imports_and_round_trips(built: Path) -> None:
    sys.path.insert(0, str(built / "out"))
    try:
        package = importlib.import_module("hostile_pkg.hostile_text")
        assert package.SPEC.device.title == HOSTILE["title"]  # exact, lone surrogate and all
        assert [m.name for m in package.RunState] == ["STOP", "RUN"]
        assert set(package.client.Control.__dataclass_fields__) == {"run", "direction", "mode"}
        assert package.IllegalFunctionError.MEANING == HOSTILE["label_quote"]
        assert package.SPEC.register("control").bits[1].label == HOSTILE["separators"]
        source = (built / "out" / "hostile_pkg" / "hostile_text" / "client.py").read_text(encoding="utf-8")
        tree = ast.parse(source)
        enum = next(n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == "RunState")
        labels = [n.value.value for n in enum.body[1:] if isinstance(n, ast.Expr) and isinstance(n.value, ast.Constant)]
        assert labels == [HOSTILE["label_quote"], HOSTILE["separators"]]  # each label's docstring, literally
        assert len(source.splitlines()) == source.count("\n")  # no separator became a line break
    finally:
        sys.path.remove(str(built / "out"))
        for key in [k for k in sys.modules if k.startswith("hostile_pkg")]:
            del sys.modules[key]


def test_hostile_text_adds_no_heading_or_row_to_the_docs(built: Path) -> None:
    page = (built / "out" / "docs" / "hostile_text.md").read_text(encoding="utf-8")
    assert "\ufffd" in page.splitlines()[0]  # the title: U+FFFD where no UTF-8 file can hold the surrogate
    for separator in LINE_BREAKS:
        assert separator not in page.replace("\n", "")
    tokens = MD.parse(page)
    headings = [tokens[i + 1].content for i, t in enumerate(tokens) if t.type == "heading_open"]
    assert not [h for h in headings if "injected" in h or h.startswith("another")], headings
    header = None
    for tok in tokens:
        if tok.type == "table_open":
            header = None
        elif tok.type == "tr_open":
            count = 0
        elif tok.type in ("th_open", "td_open"):
            count += 1
        elif tok.type == "tr_close":
            header = count if header is None else header
            assert count == header

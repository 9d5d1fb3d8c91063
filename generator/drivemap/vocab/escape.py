"""The one way map text reaches generated Python and Markdown (the templates' filters call these).

Any Unicode string, lone surrogates included, is safe in each context, and a property test over
all of Unicode (``tests/vocab/test_escaping.py``) holds them to it:

* :func:`py_literal` - a Python literal (``repr``): ``ast.literal_eval`` gives the value back;
* :func:`py_docstring` - the inside of a ``\"\"\"...\"\"\"`` docstring: a quote followed by another one or
  ending the text is escaped (a text ending in ``"`` cannot close the docstring early), and so is every
  character that is not printable (line and paragraph separators, ``\\x0b``, ``\\x0c``,
  ``\\x1c``-``\\x1e``, ``\\x85``): the docstring stays on one line and evaluates back to the text, a
  lone surrogate shown as its ``\\uXXXX`` escape (no class docstring can hold one);
* :func:`md_text` - Markdown inline text (a table cell, a heading, a paragraph): one line (every
  character ``str.splitlines`` breaks at becomes a space), no markup (``&``, ``<``, ``>`` as entities;
  ``\\``, ``|``, backticks, ``*``, ``_``, ``[``, ``]``, ``~``, ``#`` backslash-escaped) and storable as UTF-8
  (a lone surrogate, which no UTF-8 file can hold, and NUL become U+FFFD, as a Markdown reader
  would show them; whitespace at either end is dropped, as a table cell would): it renders as
  exactly the text, so mapped;
* :func:`md_comment` - the inside of an HTML comment (``--`` cannot end it).
"""

from __future__ import annotations

import re
from typing import Any

__all__ = ["LINE_BREAKS", "md_comment", "md_text", "py_docstring", "py_literal"]

#: Every character ``str.splitlines`` breaks a line at (and Markdown readers do too).
LINE_BREAKS = "\n\r\x0b\x0c\x1c\x1d\x1e\x85\u2028\u2029"
_BREAK = re.compile(f"[{re.escape(LINE_BREAKS)}]")
_UNSTORABLE = re.compile("[\x00\ud800-\udfff]")
_SURROGATE = re.compile("[\ud800-\udfff]")
#: A quote that could help close a docstring: one followed by another, or the last character.
_CLOSING_QUOTE = re.compile(r'"(?=")|"$')
_MD_ESCAPES = (("&", "&amp;"), ("\\", "\\\\"), ("|", "\\|"), ("<", "&lt;"), (">", "&gt;"), ("`", "\\`"),
               ("*", "\\*"), ("_", "\\_"), ("[", "\\["), ("]", "\\]"), ("~", "\\~"), ("#", "\\#"))


def py_literal(value: Any) -> str:
    """A Python literal for any map value: text from a map can never become code."""
    return repr(value)


def py_docstring(value: Any) -> str:
    """Text safe inside a triple-double-quoted docstring, on one line, evaluating back to ``str(value)``.

    A lone surrogate shows as its escape (the six characters ``\\ud800``): CPython cannot store one
    in a class's ``__doc__`` (the exact text reaches the code through :func:`py_literal`).
    """
    text = _SURROGATE.sub(lambda m: f"\\u{ord(m.group()):04x}", str(value))
    return _CLOSING_QUOTE.sub(r'\\"', repr(text)[1:-1])  # repr's inside never escapes '"' itself


def md_text(value: Any) -> str:
    """Markdown inline text that renders as ``str(value)`` (one line, no markup, UTF-8 storable); None is "—"."""
    if value is None:
        return "—"
    text = _UNSTORABLE.sub("\ufffd", _BREAK.sub(" ", str(value))).strip()
    for old, new in _MD_ESCAPES:
        text = text.replace(old, new)
    return text


def md_comment(value: Any) -> str:
    """Text safe inside ``<!-- ... -->``: one line, no ``--``, no lone surrogates."""
    text = _UNSTORABLE.sub("\ufffd", _BREAK.sub(" ", str(value)))
    while "--" in text:
        text = text.replace("--", "- -")
    return text


def slug(text: str) -> str:
    """The anchor a code-hosting site (GitHub) derives from a heading's text."""
    text = text.strip().lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


_CONTROL = re.compile(r"[\x00-\x1f\x7f\x85\u2028\u2029]+")


def comment_safe(text: str) -> str:
    """Map text fit for one comment line: every line break and control character becomes a space."""
    return " ".join(_CONTROL.sub(" ", text).split())

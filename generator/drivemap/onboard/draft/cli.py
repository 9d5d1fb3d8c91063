"""``drivemap draft DOCUMENT [-o maps/ID.yaml] [--model ID] [--pages 3-9] [--sheet NAME] [--assume FIELD=VALUE]
[--address-base 0|1] [--review FILE.html] [--force]``."""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import re
import signal
import sys
import tempfile
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from types import FrameType

from drivemap.frontend.project import display, load_project
from drivemap.frontend.schema import SCHEMA_PATH
from drivemap.onboard.draft.assemble import ASSUMABLE, Hints, draft
from drivemap.onboard.draft.naming import snake
from drivemap.onboard.draft.read import DocumentError, TimeLimit, read_document
from drivemap.onboard.draft.summary import print_summary
from drivemap.onboard.draft.tables import DraftError
from drivemap.onboard.draft.writer import settle


def add_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    s = sub.add_parser("draft", help="draft a map from the register tables of a manual (PDF, DOCX, XLSX, CSV, text)")
    s.add_argument("document", metavar="DOCUMENT")
    s.add_argument("-o", "--output", default=None, metavar="FILE",
                   help="the map to write (default: the project's maps folder, <model>.yaml)")
    s.add_argument("--model", default=None, help="model id (default: from the document's file name)")
    s.add_argument("--pages", default=None, metavar="A-B", help="PDF pages to read (e.g. 3-9)")
    s.add_argument("--max-pages", type=_page_count, default=400, metavar="N",
                   help=f"read at most this many PDF pages (1 to {MAX_PAGES}; default 400)")
    s.add_argument("--timeout", type=_seconds, default=300.0, metavar="S",
                   help=f"give up after this many seconds (above 0, up to {MAX_TIMEOUT:g}; default 300)")
    s.add_argument("--sheet", default=None, metavar="NAME", help="read only this sheet of a workbook (XLSX)")
    s.add_argument("--assume", action="append", default=[], metavar="FIELD=VALUE",
                   help="what the document leaves open and you know: table=holding|input|coil|discrete, "
                        "type=u16|s16|u32|s32|u64|s64|f32|f64, word_order=high_first|low_first, offset=registers|bytes "
                        "(what offsets printed beside a block's start address count); repeatable, used "
                        "only where the document states nothing, and recorded on each register it decides")
    s.add_argument("--address-base", type=int, choices=(0, 1), default=None, metavar="0|1",
                   help="plain register numbers the draft cannot place: 1 (the protocol address is one less) "
                        "or 0 (as printed)")
    s.add_argument("--review", default=None, metavar="FILE.html",
                   help="also write a review page: each table beside the page it came from, open fields, skipped rows")
    s.add_argument("--force", action="store_true", help="replace an existing output file")
    s.set_defaults(func=cmd_draft)


#: Upper bounds of --max-pages and --timeout (a day: setitimer overflows on 1e300).
MAX_PAGES = 10000
MAX_TIMEOUT = 86400.0
#: After the time limit, the alarm fires again this often until the run ends: a reader (or a library
#: it calls) that catches the first one cannot swallow it.
_REPEAT_S = 0.2
MAP_SUFFIXES = (".yaml", ".yml")


def _page_count(text: str) -> int:
    """An argparse type: a number of pages, 1 to :data:`MAX_PAGES`."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of pages") from None
    if not 1 <= value <= MAX_PAGES:
        raise argparse.ArgumentTypeError(f"{text!r}: give a number of pages from 1 up to {MAX_PAGES}")
    return value


def _seconds(text: str) -> float:
    """An argparse type: a finite number of seconds above 0, up to :data:`MAX_TIMEOUT`."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None
    if not math.isfinite(value) or not 0 < value <= MAX_TIMEOUT:
        raise argparse.ArgumentTypeError(f"{text!r}: give seconds above 0 up to {MAX_TIMEOUT:g}")
    return value


def _hints(args: argparse.Namespace) -> Hints:
    """``--assume FIELD=VALUE`` (each field once, a value the field takes) and ``--address-base``."""
    seen: dict[str, str] = {}
    for item in args.assume:
        key, sep, value = item.partition("=")
        key, value = key.strip(), value.strip()
        if not sep or key not in ASSUMABLE:
            raise DraftError(f"--assume {item!r}: give FIELD=VALUE, FIELD one of {', '.join(ASSUMABLE)}")
        if value not in ASSUMABLE[key]:
            raise DraftError(f"--assume {item!r}: {key} is one of {', '.join(ASSUMABLE[key])}")
        if key in seen and seen[key] != value:
            raise DraftError(f"--assume {key}={seen[key]} and {key}={value}: one value per field")
        seen[key] = value
    return Hints(tuple(seen.items()), args.address_base)


def _pages(text: str | None) -> tuple[int, int] | None:
    if text is None:
        return None
    m = re.fullmatch(r"\s*(\d{1,5})\s*(?:-\s*(\d{1,5}))?\s*", text)
    if not m or int(m.group(1)) < 1 or (m.group(2) and int(m.group(2)) < int(m.group(1))):
        raise DraftError(f"--pages {text!r}: give a page or a range like 3-9")
    first = int(m.group(1))
    return first, int(m.group(2) or first)


@contextlib.contextmanager
def _time_limit(seconds: float) -> Iterator[None]:
    """Raise DraftError after ``seconds`` (main thread on POSIX; elsewhere the readers' own bounds hold)."""
    if not hasattr(signal, "SIGALRM") or threading.current_thread() is not threading.main_thread():
        yield
        return

    def expire(_signum: int, _frame: FrameType | None) -> None:
        raise TimeLimit(f"time limit of {seconds:g} s reached (use --pages or --timeout)")

    old = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds, _REPEAT_S)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


@contextlib.contextmanager
def _progress(name: str, seconds: float) -> Iterator[Callable[[str], None]]:
    """A line on stderr (a terminal's: rich draws nothing elsewhere) saying what the draft is doing and
    for how long, erased at the end; yields the function that changes what it says."""
    from rich.console import Console
    from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

    console = Console(stderr=True)
    if not console.is_terminal:  # a log or a pipe gets the result, not a line a terminal would redraw
        yield lambda _what: None
        return
    with Progress(SpinnerColumn(), TextColumn("{task.description}"), TimeElapsedColumn(),
                  TextColumn(f"(time limit {seconds:g} s)"), console=console, transient=True) as bar:
        task = bar.add_task(f"{name}: reading")

        def tell(what: str) -> None:
            bar.update(task, description=f"{name}: {what}")

        yield tell


def _header(name: str, sha: str, target: Path) -> str:
    ref = Path(os.path.relpath(SCHEMA_PATH.resolve(), target.parent.resolve())).as_posix()
    return (f"# yaml-language-server: $schema={ref}\n"
            f"# Drafted by `drivemap draft` from {name}\n"
            f"# document sha256: {sha}\n"
            "# Every register names its source (page and line or row). Fields the document does not state are\n"
            "# left out and listed in each register's notes; those whose default would change the values read\n"
            "# (table, type, word order, scale) are in its `review:` list: state them, then delete the item.\n")


def _write(target: Path, text: str, force: bool) -> None:
    """Atomically: a temporary file beside the target, then renamed (or linked: no overwrite)."""
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # as a file the user wrote (mkstemp makes it 0600)
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as handle:
            handle.write(text)
            handle.flush()
            os.fsync(handle.fileno())
        if force:
            os.replace(tmp, target)
        else:
            os.link(tmp, target)  # fails if the target appeared meanwhile: nothing is overwritten
            os.unlink(tmp)
    except FileExistsError:
        raise DraftError(f"{display(target)} exists; not overwritten (use --force)") from None
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def run(args: argparse.Namespace) -> int:
    from rich.console import Console

    path = Path(args.document)
    model = args.model or (Path(args.output).stem if args.output else snake(path.stem, "device"))
    if args.output and Path(args.output).suffix.lower() not in MAP_SUFFIXES:
        raise DraftError(f"-o {args.output}: a map is a YAML file: name it {Path(args.output).stem}.yaml")
    if args.output and Path(args.output).stem != model:
        raise DraftError(f"--model {model} and -o {args.output}: a map's file name is its model id")
    if not re.fullmatch(r"[a-z][a-z0-9_]*", model):
        raise DraftError(f"model id {model!r} must be a lower-case identifier (--model)")
    target = Path(args.output) if args.output else load_project().maps_folder() / f"{model}.yaml"
    if os.path.lexists(target) and not args.force:
        raise DraftError(f"{display(target)} exists; not overwritten (use --force)")
    hints = _hints(args)
    review = Path(args.review) if args.review else None
    if review is not None:
        if review.suffix.lower() not in (".html", ".htm"):
            raise DraftError(f"--review {args.review}: the review page is an HTML file (name it *.html)")
        if os.path.lexists(review) and not args.force:
            raise DraftError(f"{display(review)} exists; not overwritten (use --force)")
    with _time_limit(args.timeout), _progress(path.name, args.timeout) as tell:
        source = read_document(path, _pages(args.pages), args.max_pages, args.timeout, tell, args.sheet)
        rows = sum(len(t.rows) for t in source.tables)
        tell(f"drafting {rows:,} row{'s' if rows != 1 else ''} of {len(source.tables)} "
             f"table{'s' if len(source.tables) != 1 else ''}")
        result = draft(source, model, hints)
        if not result.registers:
            count = len(result.skipped)
            why = f" ({count} row{'s' if count != 1 else ''} skipped: {result.skipped[0].reason})" if count else ""
            sheets = [t.label for t in source.tables if t.label.startswith("sheet ")]
            tried = f"; tried {', '.join(sheets)} (--sheet NAME picks one)" if sheets else ""
            offsets = [s for s in result.skipped if "from a base address" in s.reason]
            if offsets:  # register tables were found; their numbers are not addresses
                raise DraftError(f"no register drafted: {len(offsets)} rows of register tables print offsets from "
                                 f"a base address, not addresses (first: {offsets[0].where}: {offsets[0].reason})")
            raise DraftError(f"no register table found: no table with an address column{why}{tried}")
        tell(f"checking the map of {len(result.registers):,} registers")
        text, errors = settle(result, _header(source.name, source.sha256, target), display(target))
    if errors:
        for d in errors:
            print(d.format(), file=sys.stderr)
        print(f"{len(errors)} errors: the draft does not validate; nothing written", file=sys.stderr)
        return 1
    _write(target, text, args.force)
    if review is not None:
        from drivemap.onboard.draft.review_page import render

        _write(review, render(path, source, result, display(target)), args.force)
    print_summary(Console(width=max(120, Console().width)), source, result, display(target), model)
    return 0


def cmd_draft(args: argparse.Namespace) -> int:
    try:
        return run(args)
    except TimeLimit as exc:
        print(f"{display(args.document)}: error: {exc}", file=sys.stderr)
        return 1
    except DocumentError as exc:  # at a place of the document
        print(f"{display(args.document)}:{exc.line}:{exc.column}: error: {exc}", file=sys.stderr)
        return 1
    except DraftError as exc:
        print(f"{display(args.document)}: error: {exc}", file=sys.stderr)
        return 1

"""The ``drivemap`` command: validate | build | check | examples | export | new | simulate | schema |
gateway, and at the drive (:mod:`drivemap.live`): read | write | watch | scan | verify.

Every verb acts on the project of the working directory (:mod:`drivemap.frontend.project`); explicit paths
and flags win over its ``[tool.drivemap]`` settings. Every bad input ends in ``path:line:col:
error: ...`` lines and exit status 1, never a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence

from drivemap import __version__
from drivemap.cli.common import Parser, UsageError, report
from drivemap.diagnostics import CompileError
from drivemap.frontend.project import display

__all__ = ["UsageError", "main", "parser"]


#: Which function adds each verb's parser (module, function); a function may add several verbs. A run
#: imports only the module of the verb it runs (``drivemap build`` loads no draft, import or live
#: code); ``--help``, no verb or an unknown one builds them all.
VERBS: dict[str, tuple[str, str]] = {
    **dict.fromkeys(("validate", "build", "check", "examples"), ("drivemap.cli.verbs", "check_parsers")),
    "export": ("drivemap.cli.export", "export_parser"),
    **dict.fromkeys(("new", "migrate", "schema", "simulate"), ("drivemap.cli.verbs", "other_parsers")),
    **dict.fromkeys(("read", "write", "watch", "scan", "verify"), ("drivemap.live", "add_parsers")),
    "draft": ("drivemap.onboard.draft.cli", "add_parser"),
    "import": ("drivemap.onboard.importers.cli", "add_parser"),
    "probe": ("drivemap.onboard.probe_cli", "add_parser"),
    "list": ("drivemap.cli.listing", "add_parser"),
    "compare": ("drivemap.cli.compare", "add_parser"),
    "gateway": ("drivemap.cli.verbs", "gateway_parser"),
}


def _verb(argv: Sequence[str]) -> str | None:
    """The verb ``argv`` runs (its first word that is not an option), if drivemap has it."""
    first = next((w for w in argv if not w.startswith("-")), None)
    return first if first in VERBS else None


def parser(argv: Sequence[str] | None = None) -> argparse.ArgumentParser:
    """The command's parser: with ``argv``, only the sub-parser of the verb it names (all of them else)."""
    p = Parser(prog="drivemap", description="Register-map compiler for Modbus drives.")
    p.add_argument("--version", action="version", version=f"drivemap {__version__}")
    sub = p.add_subparsers(dest="command", required=True, parser_class=Parser)
    verb = _verb(argv) if argv is not None else None
    wanted = [VERBS[verb]] if verb is not None else list(dict.fromkeys(VERBS.values()))
    for module, function in wanted:
        getattr(importlib.import_module(module), function)(sub)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    try:
        args, rest = parser(sys.argv[1:] if argv is None else argv).parse_known_args(argv)
        if rest and args.command != "export" and not getattr(args, "takes_rest", False):
            raise UsageError(f"drivemap {args.command}", f"unrecognized arguments: {' '.join(rest)}")
        args.rest = rest
        from drivemap import cache

        with cache.disabled(bool(getattr(args, "no_cache", False))):
            result: int = args.func(args)
        return result
    except UsageError as exc:
        print(f"{exc}\n(see `drivemap --help`)", file=sys.stderr)
        return 1
    except CompileError as exc:
        return report(exc.diagnostics)
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        return 0
    except OSError as exc:  # a path the system refuses that no verb located itself: still no traceback
        where = display(os.fsdecode(exc.filename)) if exc.filename else "drivemap"
        print(f"{where}:1:1: error: {exc.strerror or exc}", file=sys.stderr)
        print("1 error", file=sys.stderr)
        return 1



"""The ``drivemap`` command: validate | build | check | examples | export | new | simulate | schema |
gateway, and at the drive (:mod:`drivemap.live`): read | write | watch | scan | verify.

Every verb acts on the project of the working directory (:mod:`drivemap.frontend.project`); explicit paths
and flags win over its ``[tool.drivemap]`` settings. Every bad input ends in ``path:line:col:
error: ...`` lines and exit status 1, never a traceback.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence

from drivemap import __version__
from drivemap.cli.common import Parser, UsageError, report
from drivemap.cli.export import export_parser
from drivemap.cli.verbs import check_parsers, gateway_parser, other_parsers
from drivemap.diagnostics import CompileError
from drivemap.frontend.project import display

__all__ = ["UsageError", "main", "parser"]


def parser() -> argparse.ArgumentParser:
    p = Parser(prog="drivemap", description="Register-map compiler for Modbus drives.")
    p.add_argument("--version", action="version", version=f"drivemap {__version__}")
    sub = p.add_subparsers(dest="command", required=True, parser_class=Parser)
    check_parsers(sub)  # validate, build, check, examples
    export_parser(sub)
    other_parsers(sub)  # new, migrate, schema, simulate
    from drivemap.live import add_parsers

    add_parsers(sub)  # read, write, watch, scan, verify: a live device by name
    from drivemap.onboard.draft.cli import add_parser as draft_parser

    draft_parser(sub)  # draft: a map from the register tables of a manual
    from drivemap.onboard.importers.cli import add_parser as import_parser
    from drivemap.onboard.probe_cli import add_parser as probe_parser

    import_parser(sub)  # import: Home Assistant, ESPHome, SunSpec, CSV definitions -> a map
    probe_parser(sub)  # probe: what a live device answers, as a skeleton map
    from drivemap.cli.compare import add_parser as compare_parser

    compare_parser(sub)  # compare: where two maps of one device disagree
    gateway_parser(sub)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    try:
        args, rest = parser().parse_known_args(argv)
        if rest and args.command != "export" and not getattr(args, "takes_rest", False):
            raise UsageError(f"drivemap {args.command}", f"unrecognized arguments: {' '.join(rest)}")
        args.rest = rest
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



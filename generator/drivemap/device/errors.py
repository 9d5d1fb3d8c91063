"""Exit codes and the one-line errors of the live verbs (read, write, watch, scan, verify).

Every failure a person at the drive can act on ends in one line on stderr,
``drivemap VERB: error: ...``, and one of these exit codes (never a traceback):

====  ==========================================================================================
code  meaning
====  ==========================================================================================
0     done (verify: the map and the device agree)
1     bad input: command line, map, a value that does not fit its register (located errors)
2     cannot reach the device: unreachable host or port, no such serial device, permission denied
3     no answer from that unit (silence after every retry)
4     garbled replies: bytes arrive but never form a valid frame (wrong baud rate or parity?)
5     the device answered with an exception (its code, name and meaning from the map)
6     verify: the map and the device disagree (see the report)
7     the device is not the map's: an identity register holds another value (write refuses)
130   interrupted (Ctrl-C)
====  ==========================================================================================
"""

from __future__ import annotations

import argparse
import functools
import logging
import sys
from collections.abc import Callable

from drivemap.runtime.errors import DriveError

EXIT_OK = 0
EXIT_INPUT = 1
EXIT_CONNECT = 2
EXIT_NO_ANSWER = 3
EXIT_GARBLED = 4
EXIT_DEVICE_EXCEPTION = 5
EXIT_DISAGREE = 6
EXIT_IDENTITY = 7
EXIT_INTERRUPTED = 130

EXIT_CODES: dict[int, str] = {
    EXIT_OK: "done (verify: map and device agree)",
    EXIT_INPUT: "bad input (command line, map, value); the error is located",
    EXIT_CONNECT: "cannot reach the device (host/port unreachable, no such serial device, permission denied)",
    EXIT_NO_ANSWER: "no answer from that unit",
    EXIT_GARBLED: "garbled replies (wrong baud rate or parity?), or replies that do not answer the request",
    EXIT_DEVICE_EXCEPTION: "the device answered with an exception",
    EXIT_DISAGREE: "verify: map and device disagree",
    EXIT_IDENTITY: "the device is not the map's (identity check; --no-identity-check overrides)",
    EXIT_INTERRUPTED: "interrupted (Ctrl-C)",
}


class LiveError(Exception):
    """A failure at the drive: printed as one line, exit status ``code``."""

    def __init__(self, code: int, message: str) -> None:
        super().__init__(message)
        self.code = code
        self.message = message


def epilog() -> str:
    """The exit-code table for ``--help``."""
    return "exit codes:\n" + "\n".join(f"  {code:<4} {text}" for code, text in EXIT_CODES.items())


def quiet_libraries(debug: bool) -> None:
    """pymodbus logs connection failures and timeouts itself; the verbs say it in one line instead.

    ``--debug`` shows every frame in hex (the ``drivemap`` logger) instead.
    """
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL + 1)
    drivemap_log = logging.getLogger("drivemap")
    if debug:
        handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(logging.Formatter("%(asctime)s %(message)s"))
        drivemap_log.addHandler(handler)
        drivemap_log.setLevel(logging.DEBUG)
    else:
        drivemap_log.setLevel(logging.ERROR)


def verb(name: str) -> Callable[[Callable[[argparse.Namespace], int]], Callable[[argparse.Namespace], int]]:
    """Wrap a verb: LiveError / stray DriveError -> one line and its exit code."""

    def wrap(func: Callable[[argparse.Namespace], int]) -> Callable[[argparse.Namespace], int]:
        @functools.wraps(func)
        def run(args: argparse.Namespace) -> int:
            quiet_libraries(getattr(args, "debug", False))
            try:
                return func(args)
            except LiveError as exc:
                print(f"drivemap {name}: error: {exc.message}", file=sys.stderr)
                return exc.code
            except DriveError as exc:  # a runtime error no verb explained: still one line
                print(f"drivemap {name}: error: {exc}", file=sys.stderr)
                return EXIT_CONNECT

        return run

    return wrap

"""The command line of a simulator: ``drivemap simulate MODEL`` and ``python -m <package>.simulator``.

Both take the same options (:func:`add_arguments`), build the simulator from a factory (a generated
``Simulator`` class), serve it with :class:`~drivemap.runtime.sim.serve.SimServer` until Ctrl-C or
SIGTERM and exit 0, or print one error line and exit 1 (a state file's errors are located:
``path:line:col: error: ...``).
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import math
import signal
import sys
from collections.abc import Callable, Sequence
from typing import Any

from drivemap.runtime.sim.presets import PresetError, from_command_line, from_file
from drivemap.runtime.sim.serve import SimServer
from drivemap.runtime.sim.simulator import Simulator, SimulatorError, StateFileError
from drivemap.runtime.sim.tcp import IDLE_TIMEOUT_S, MAX_IDLE_TIMEOUT_S

__all__ = ["SimulatorFactory", "add_arguments", "main", "parse_tcp", "serve_cli"]

#: ``factory(units, state_file=..., realistic_timing=...)`` -> Simulator (a generated ``Simulator`` class).
SimulatorFactory = Callable[..., Simulator]


def parse_tcp(text: str) -> tuple[str, int]:
    """``HOST:PORT`` (``[::1]:5020`` for IPv6) -> (host, port)."""
    host, sep, port = text.rpartition(":")
    if not sep or not host or not (port.isascii() and port.isdigit()) or not 0 <= int(port) <= 65535:
        raise SimulatorError(f"--tcp wants HOST:PORT, not {text!r}")
    return host.strip("[]"), int(port)


def serve_cli(args: argparse.Namespace) -> int:
    """``drivemap simulate``: serve until Ctrl-C / SIGTERM, then exit 0 (1 on an error, located when it can be)."""
    try:
        return run(args.factory, args)
    except (StateFileError, PresetError) as exc:  # already located: path:line:col: error: ...
        print(exc, file=sys.stderr)
        return 1
    except (SimulatorError, RuntimeError, OSError) as exc:
        print(f"drivemap simulate: error: {exc}", file=sys.stderr)
        return 1


def _check_options(args: argparse.Namespace) -> None:
    """Options that would be ignored or cannot work are refused, not silently dropped."""
    if args.tcp and args.mode is not None:
        raise SimulatorError("--mode is a serial framing (rtu or ascii); Modbus TCP has its own: drop --mode or use --serial")
    if args.tcp and args.baudrate is not None:
        raise SimulatorError("--baudrate is a serial setting; drop it with --tcp")
    idle = getattr(args, "idle_timeout", None)
    if idle is not None and not args.tcp:
        raise SimulatorError("--idle-timeout is a Modbus TCP setting; drop it with --serial")
    if idle is not None and not (math.isfinite(idle) and 0 < idle <= MAX_IDLE_TIMEOUT_S):
        raise SimulatorError(f"--idle-timeout {idle:g}: give seconds above 0 up to {MAX_IDLE_TIMEOUT_S:g}")
    if args.baudrate is not None and not 50 <= args.baudrate <= 4_000_000:
        raise SimulatorError(f"--baudrate {args.baudrate}: give a serial baud rate (50 to 4000000)")


def run(factory: SimulatorFactory, args: argparse.Namespace, prog: str = "drivemap") -> int:
    """Build the simulator from parsed options and serve it in the foreground."""
    _check_options(args)
    kwargs: dict[str, Any] = {"state_file": args.state, "realistic_timing": args.realistic_timing}
    presets = presets_of(factory, args, prog)
    if presets:
        kwargs["presets"] = presets
    if getattr(args, "refuse_advised_while_running", False):
        kwargs["refuse_advised_while_running"] = True
    if getattr(args, "reply_quirks", None):
        kwargs["reply_quirks"] = args.reply_quirks
    sim = factory(args.units or [1], **kwargs)
    server = SimServer(
        sim,
        tcp=parse_tcp(args.tcp) if args.tcp else None,
        serial=args.serial,
        mode=args.mode,
        baudrate=args.baudrate,
        allow_remote=args.allow_remote,
        idle_timeout=getattr(args, "idle_timeout", None),
    )
    asyncio.run(_serve_until_signal(server))
    return 0


def presets_of(factory: SimulatorFactory, args: argparse.Namespace, prog: str) -> list[tuple[str, Any]]:
    """``--values FILE`` then ``--set NAME=VALUE`` (later ones win), checked against the map."""
    spec = getattr(factory, "spec", None) or factory([*(args.units or [1])][:1]).spec
    reader = getattr(factory, "read_values", None)  # drivemap simulate: YAML too
    enums = getattr(factory, "enum_names", None)  # drivemap simulate: enum members by name
    out = from_file(spec, args.values, reader, enums) if getattr(args, "values", None) else []
    texts = getattr(args, "presets", None) or []
    if texts:
        out += from_command_line(spec, texts, sys.argv[1:], prog, dict(out), enums)
    return out


async def _serve_until_signal(server: SimServer) -> None:
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(NotImplementedError, RuntimeError):
            loop.add_signal_handler(sig, stop.set)
    await server.start()
    try:
        print(server.describe(), flush=True)
        await stop.wait()
    finally:
        await server.stop()
        print(f"{server.sim.spec.name} simulator stopped", flush=True)


def add_arguments(parser: argparse.ArgumentParser, *, with_model: bool) -> None:
    """The options of ``drivemap simulate`` (also used by generated ``simulator.py`` modules)."""
    if with_model:
        parser.add_argument("model")
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--tcp", metavar="HOST:PORT")
    where.add_argument("--serial", metavar="DEVICE")
    parser.add_argument("--mode", choices=["rtu", "ascii"], default=None)
    parser.add_argument("--baudrate", type=int, default=None)
    parser.add_argument("--unit", type=int, action="append", dest="units")
    parser.add_argument("--state", default=None, help="JSON file keeping EEPROM-class registers across restarts")
    parser.add_argument("--realistic-timing", action="store_true")
    parser.add_argument("--refuse-advised-while-running", action="store_true",
                        help="also refuse (busy) writes the manual only advises against while the motor runs")
    parser.add_argument("--reply-quirk", action="append", dest="reply_quirks", metavar="QUIRK",
                        help="answer in a non-standard reply form the map lists (e.g. two_byte_byte_count)")
    parser.add_argument("--allow-remote", action="store_true", help="allow binding to a non-loopback address")
    parser.add_argument("--idle-timeout", type=float, default=None, metavar="S",
                        help=f"close a TCP connection that sends nothing for S seconds (default {IDLE_TIMEOUT_S:g}; "
                             f"above 0, up to {MAX_IDLE_TIMEOUT_S:g})")
    parser.add_argument("--set", action="append", dest="presets", metavar="NAME=VALUE",
                        help="start with this engineering value (repeatable; checked against the map): "
                             "--set phase_1_voltage=230.1 --set digital_speed[0]=1500")
    parser.add_argument("--values", metavar="FILE",
                        help="start with the engineering values of this file ({\"NAME\": VALUE, ...}; drivemap "
                             "simulate reads YAML too; --set wins over it)")


def main(model: str, factory: SimulatorFactory, argv: Sequence[str] | None = None) -> int:
    """Entry point of a generated ``simulator.py``: same options as ``drivemap simulate``."""
    module = getattr(factory, "__module__", "") or f"{model}.simulator"
    parser = argparse.ArgumentParser(prog=f"python -m {module}", description=f"Run the {model} simulator.")
    add_arguments(parser, with_model=False)
    args = parser.parse_args(argv)
    args.model = model
    try:
        return run(factory, args, prog=f"python -m {module}")
    except (StateFileError, PresetError) as exc:
        print(exc, file=sys.stderr)
        return 1
    except (SimulatorError, RuntimeError, OSError) as exc:
        print(f"{model} simulator: error: {exc}", file=sys.stderr)
        return 1

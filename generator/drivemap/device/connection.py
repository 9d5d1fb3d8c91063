"""Connection options shared by every live verb, their defaults from the map, and why a link fails.

``--tcp HOST[:PORT]`` (Modbus TCP), ``--rtu-over-tcp HOST:PORT`` (a serial gateway passing RTU
frames), ``--serial DEV [--mode rtu|ascii --baudrate N --parity none|even|odd --stop-bits N]``,
``--unit N``, ``--timeout S``, ``--retries N``. Mode, baud rate, parity, stop bits, response
timeout and retries default to the map's; a serial setting the map does not give must be passed
(the error lists what the map allows), since drivemap never guesses.
"""

from __future__ import annotations

import argparse
import errno
import math
import os
import socket
import termios
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

from drivemap.device.errors import (
    EXIT_CONNECT,
    EXIT_DEVICE_EXCEPTION,
    EXIT_GARBLED,
    EXIT_INPUT,
    EXIT_NO_ANSWER,
    LiveError,
)
from drivemap.device.target import Target
from drivemap.runtime.client.transport.bus import Bus
from drivemap.runtime.errors import DeviceException, DriveTimeout, TransportError

PARITIES = {"none": "none", "n": "none", "even": "even", "e": "even", "odd": "odd", "o": "odd"}
_LETTER = {"none": "N", "even": "E", "odd": "O"}


@dataclass(frozen=True)
class Link:
    """Resolved connection settings."""

    kind: str  # "tcp" | "rtu-over-tcp" | "serial"
    host: str = ""
    port: int = 0
    device: str = ""
    mode: str = "rtu"
    baudrate: int | None = None
    parity: str = "none"
    stop_bits: int = 1
    data_bits: int = 8
    unit: int = 1
    timeout: float | None = None
    retries: int | None = None

    @property
    def serial(self) -> bool:
        return self.kind == "serial"

    @property
    def bits_per_char(self) -> int:
        return 1 + self.data_bits + (0 if self.parity == "none" else 1) + self.stop_bits

    def line(self) -> str:
        """``serial /dev/ttyUSB0 rtu 19200 8E1`` / ``tcp 127.0.0.1:502``."""
        if self.serial:
            return (f"serial {self.device} {self.mode} {self.baudrate} "
                    f"{self.data_bits}{_LETTER[self.parity]}{self.stop_bits}")
        return f"{self.kind} {self.host}:{self.port}"

    def describe(self) -> str:
        return f"unit {self.unit} on {self.line()}"


def add_connection_arguments(parser: argparse.ArgumentParser, *, unit: bool = True) -> None:
    g = parser.add_argument_group("connection (defaults from the map)")
    where = g.add_mutually_exclusive_group(required=True)
    where.add_argument("--tcp", metavar="HOST[:PORT]", help="Modbus TCP (port 502 unless given)")
    where.add_argument("--rtu-over-tcp", metavar="HOST:PORT", help="RTU frames over TCP (serial gateways)")
    where.add_argument("--serial", metavar="DEV", help="serial device, e.g. /dev/ttyUSB0")
    g.add_argument("--mode", choices=["rtu", "ascii"], default=None, help="serial framing (default: the map's)")
    g.add_argument("--baudrate", type=int, default=None, metavar="N", help="serial baud rate (default: the map's)")
    g.add_argument("--parity", default=None, metavar="none|even|odd", help="serial parity (default: the map's)")
    g.add_argument("--stop-bits", type=int, choices=[1, 2], default=None, help="serial stop bits (default: the map's)")
    if unit:
        g.add_argument("--unit", type=int, default=None, metavar="N", help="unit id (default: 1, or the map's lowest)")
        g.add_argument("--no-identity-check", action="store_true",
                       help="do not read the map's identity registers first (write then writes to any device)")
    g.add_argument("--timeout", type=seconds(0.0, 600.0, zero=False), default=None, metavar="S",
                   help="response timeout (default: the map's)")
    g.add_argument("--retries", type=int, default=None, metavar="N", help="retries after a timeout (default: the map's)")
    g.add_argument("--debug", action="store_true", help="log every frame in hex on stderr")


def seconds(low: float, high: float, *, zero: bool = True) -> Callable[[str], float]:
    """An argparse type: a finite number of seconds in [low, high] (above ``low`` unless ``zero``)."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None
        if not math.isfinite(value) or value < low or value > high or (not zero and value == low):
            raise argparse.ArgumentTypeError(f"{text!r}: give seconds {'from' if zero else 'above'} {low:g} "
                                             f"up to {high:g}")
        return value

    return parse


def _host_port(text: str, option: str, default_port: int | None) -> tuple[str, int]:
    host, sep, port = text.rpartition(":")
    if not sep or "]" in port:
        host, port = text, ""
    host = host.strip("[]")
    if not port:
        if default_port is None:
            raise LiveError(EXIT_INPUT, f"{option} wants HOST:PORT, not {text!r}")
        return host, default_port
    if not (port.isascii() and port.isdigit()) or not 0 < int(port) <= 65535 or not host:
        raise LiveError(EXIT_INPUT, f"{option} wants HOST:PORT, not {text!r}")
    return host, int(port)


def resolve_link(args: argparse.Namespace, target: Target | None, *, unit: int | None = None) -> Link:
    """The link the options ask for, defaults from the map of ``target`` (None: no map, scan)."""
    if args.timeout is not None and args.timeout <= 0:
        raise LiveError(EXIT_INPUT, "--timeout must be positive")
    if args.retries is not None and args.retries < 0:
        raise LiveError(EXIT_INPUT, "--retries must be >= 0")
    chosen = unit if unit is not None else getattr(args, "unit", None)
    base = Link("tcp", unit=chosen if chosen is not None else _default_unit(target),
                timeout=args.timeout, retries=args.retries)
    if args.tcp:
        host, port = _host_port(args.tcp, "--tcp", 502)
        return replace(base, kind="tcp", host=host, port=port)
    if args.rtu_over_tcp:
        host, port = _host_port(args.rtu_over_tcp, "--rtu-over-tcp", None)
        return replace(base, kind="rtu-over-tcp", host=host, port=port)
    return serial_link(args, target, base)


def _default_unit(target: Target | None) -> int:
    if target is None or target.spec.protocol.valid_unit(1):
        return 1
    return target.spec.protocol.unit_min


def serial_link(args: argparse.Namespace, target: Target | None, base: Link) -> Link:
    spec = target.spec.protocol.serial if target is not None else None
    mode = args.mode or (spec.mode if spec else "rtu")
    if target is not None and mode not in target.spec.protocol.modes:
        raise LiveError(EXIT_INPUT, f"{target.model.name} does not speak Modbus {mode.upper()} "
                                    f"(the map lists {', '.join(target.spec.protocol.modes)})")
    baudrate = args.baudrate or (spec.baudrate if spec else None)
    if baudrate is None:
        raise LiveError(EXIT_INPUT, f"the map gives no default baud rate; pass --baudrate N{_listed(target, 'baudrates')}"
                                    f" (or find it: drivemap scan --serial {args.serial})")
    parity_text = args.parity if args.parity is not None else (spec.parity if spec else None)
    if parity_text is None:
        raise LiveError(EXIT_INPUT, f"the map gives no default parity; pass --parity none|even|odd{_listed(target, 'parity')}"
                                    f" (or find it: drivemap scan --serial {args.serial})")
    parity = PARITIES.get(str(parity_text).lower())
    if parity is None:
        raise LiveError(EXIT_INPUT, f"--parity wants none, even or odd, not {parity_text!r}")
    stop_bits = args.stop_bits or (spec.stop_bits if spec and spec.stop_bits else 1)
    return replace(base, kind="serial", device=args.serial, mode=mode, baudrate=baudrate, parity=parity,
                   stop_bits=stop_bits, data_bits=spec.data_bits if spec else 8)


def _listed(target: Target | None, what: str) -> str:
    if target is None:
        return ""
    values = sorted({str(v) for port in target.model.protocol.ports for v in getattr(port, what)},
                    key=lambda v: (len(v), v))
    return f" (the map lists {', '.join(values)})" if values else ""


def make_bus(link: Link) -> Bus:
    if link.kind == "tcp":
        return Bus.tcp(link.host, link.port, timeout=link.timeout, retries=link.retries)
    if link.kind == "rtu-over-tcp":
        return Bus.rtu_over_tcp(link.host, link.port, timeout=link.timeout, retries=link.retries)
    return Bus.serial(link.device, None, timeout=link.timeout, retries=link.retries, mode=link.mode,
                      baudrate=link.baudrate, parity=link.parity, stopbits=link.stop_bits, bytesize=link.data_bits)


def open_bus(link: Link) -> Bus:
    """A connected bus, or a :class:`LiveError` saying why the port cannot be reached."""
    if link.serial:
        check_serial_device(link.device)
    bus = make_bus(link)
    try:
        bus.connect()
    except TransportError:
        bus.close()
        raise LiveError(EXIT_CONNECT, why_unreachable(link)) from None
    return bus


def check_serial_device(device: str) -> None:
    """Open the device the way pyserial will, to say exactly why it cannot be used."""
    try:
        fd = os.open(device, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    except OSError as exc:
        raise LiveError(EXIT_CONNECT, _serial_reason(device, exc)) from None
    try:
        termios.tcgetattr(fd)
    except termios.error:
        raise LiveError(EXIT_CONNECT, f"{device} is not a serial device") from None
    finally:
        os.close(fd)


def _serial_reason(device: str, exc: OSError) -> str:
    if exc.errno in (errno.EACCES, errno.EPERM):
        return (f"permission denied on {device}: add your user to the group that owns it "
                f"(usually: sudo usermod -aG dialout $USER, then log in again)")
    if exc.errno == errno.ENOENT:
        return f"no serial device {device} (is the adapter plugged in? see ls /dev/serial/by-id/)"
    if exc.errno == errno.EBUSY:
        return f"{device} is busy: another program has it open"
    return f"cannot open {device}: {os.strerror(exc.errno or 0)}"


def why_unreachable(link: Link) -> str:
    """Why a TCP link does not connect (tried once more with a plain socket for the reason)."""
    if link.serial:
        return f"cannot open {link.device} as {link.line().split(' ', 2)[2]}: the port refuses these settings"
    try:
        with socket.create_connection((link.host, link.port), timeout=link.timeout or 3.0):
            pass
    except socket.gaierror:
        return f"unknown host {link.host!r} ({link.kind})"
    except TimeoutError:
        return f"{link.host}:{link.port} does not accept connections (timed out): is the address right?"
    except OSError as exc:
        reason = os.strerror(exc.errno) if exc.errno else str(exc)
        return f"cannot connect to {link.host}:{link.port} ({link.kind}): {reason.lower()}; is the device or gateway on and the port right?"
    return f"cannot connect to {link.host}:{link.port} ({link.kind})"


def explain(exc: Exception, link: Link, target: Target | None, what: str, *, garbled: bool,
            rejected: str | None = None) -> LiveError:
    """One actionable line for a failed request (``what``: what it was doing; ``rejected``: why the
    last reply that came back was not the answer, when one did)."""
    if isinstance(exc, DeviceException):
        return LiveError(EXIT_DEVICE_EXCEPTION, device_exception_text(exc, link, target, what))
    if isinstance(exc, DriveTimeout) and rejected:
        return LiveError(EXIT_GARBLED, f"{what}: {link.describe()} answered, but not what was asked ({rejected}); "
                                       "is this the device of this map, and the unit id right?")
    if isinstance(exc, DriveTimeout):
        if garbled:
            hint = ("wrong baud rate or parity? find them with: drivemap scan --serial " + link.device
                    if link.serial else
                    "is it a serial gateway passing RTU frames (--rtu-over-tcp) rather than Modbus TCP?"
                    if link.kind == "tcp" else "is it Modbus TCP (--tcp) rather than RTU over TCP?")
            return LiveError(EXIT_GARBLED, f"{what}: replies from {link.line()} are garbled ({hint})")
        return LiveError(EXIT_NO_ANSWER, f"{what}: no answer from {link.describe()} "
                                         f"(is the unit id right? list the units with: drivemap scan {_scan_hint(link)})")
    if isinstance(exc, TransportError) and "closed" in str(exc) and not link.serial:
        # the connection was made; the peer dropped it on our request instead of answering
        hint = ("is it Modbus TCP (--tcp) rather than RTU over TCP?" if link.kind != "tcp" else
                "is it a serial gateway passing RTU frames (--rtu-over-tcp) rather than Modbus TCP?")
        return LiveError(EXIT_NO_ANSWER, f"{what}: no answer from {link.describe()}: the peer closed the connection "
                                         f"on the request ({hint})")
    if isinstance(exc, TransportError):
        return LiveError(EXIT_CONNECT, f"{what}: {link.line()}: {exc}")
    return LiveError(EXIT_CONNECT, f"{what}: {exc}")


def _scan_hint(link: Link) -> str:
    if link.serial:
        return f"--serial {link.device}"
    return f"--{link.kind} {link.host}:{link.port}"


def device_exception_text(exc: DeviceException, link: Link, target: Target | None, what: str) -> str:
    where = ""
    if target is not None:
        line = target.exception_line(exc.code)
        where = f" [{target.model.path}:{line}]" if line else " [code not in the map]"
    return (f"{what}: unit {link.unit} answered exception {exc.code:02X}h {exc.name} to function "
            f"{exc.function_code:02X}h: {exc.meaning}{where}")


class Watch:
    """Notes what the bus received during one operation, to tell silence from garbage."""

    def __init__(self, bus: Bus) -> None:
        self.bus = bus
        self.before = bus.stats.bytes_garbled
        self.rejected_before = bus.stats.rejected

    @property
    def garbled(self) -> bool:
        return self.bus.stats.bytes_garbled > self.before

    @property
    def rejected(self) -> str | None:
        """What the last refused reply was, when one came during the operation."""
        return getattr(self.bus, "last_rejected", None) if self.bus.stats.rejected > self.rejected_before else None


def run(bus: Bus, link: Link, target: Target | None, what: str, func: Any, *args: Any) -> Any:
    """``func(*args)`` with every runtime failure explained (:func:`explain`)."""
    watch = Watch(bus)
    try:
        return func(*args)
    except (DeviceException, TransportError) as exc:
        raise explain(exc, link, target, what, garbled=watch.garbled, rejected=watch.rejected) from None

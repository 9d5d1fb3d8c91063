"""``drivemap gateway CONFIG.yaml``: the command line (argparse only at import time; the rest on use)."""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import logging
import signal
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from drivemap.diagnostics import CompileError, Diagnostic, Location

if TYPE_CHECKING:
    from drivemap.frontend.project import Project
    from drivemap.gateway.config import GatewayConfig
    from drivemap.gateway.service import Gateway

#: The example configuration shipped in the package (the same file as docs/examples/plant.yaml).
EXAMPLE = Path(__file__).resolve().parent.parent / "data" / "plant.yaml"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("config", metavar="CONFIG.yaml", nargs="?", help="the gateway configuration")
    parser.add_argument("--check", action="store_true", help="validate the configuration, print what would run, exit")
    parser.add_argument("--example", action="store_true",
                        help="print a working example configuration (docs/examples/plant.yaml; without its OPC UA "
                             "part unless drivemap[opcua] is installed) and exit")
    parser.add_argument("--broker", metavar="HOST[:PORT]", help="the MQTT broker, replacing the configuration's "
                        "mqtt.host (and mqtt.port)")
    parser.add_argument("--log-level", default="info", choices=["debug", "info", "warning", "error"])


def _has_opcua() -> bool:
    try:
        import asyncua  # noqa: F401
    except ImportError:
        return False
    return True


def example_text(opcua: bool | None = None) -> str:
    """The example configuration; without its ``opcua:`` block when OPC UA is not installed."""
    text = EXAMPLE.read_text(encoding="utf-8")
    if opcua if opcua is not None else _has_opcua():
        return text
    lines = text.splitlines(keepends=True)
    start = next(i for i, line in enumerate(lines) if line.startswith("opcua:"))
    end = next(i for i in range(start + 1, len(lines)) if lines[i][:1] not in (" ", "#", "\n", ""))
    note = "# (OPC UA left out: pip install 'drivemap[opcua]' and run drivemap gateway --example again)\n"
    return "".join([*lines[:start], note, *lines[end:]])


def parse_broker(text: str) -> tuple[str, int | None]:
    """HOST, [HOST]:PORT or HOST:PORT of ``--broker``; a bad port is a usage error (exit 1)."""
    host, sep, port = text.rpartition(":") if not text.endswith("]") else (text, "", "")
    if not sep or ("]" not in host and ":" in host):  # no port, or a bare IPv6 address
        host, port = text, ""
    host = host.strip("[]")
    if not host or (port and (not port.isascii() or not port.isdigit() or not 1 <= int(port) <= 65535)):
        raise CompileError([Diagnostic(Location("--broker", 1, 1), f"--broker {text!r}: give HOST or HOST:PORT "
                                       "(port 1..65535)")])
    return host, int(port) if port else None


def summary(cfg: GatewayConfig, gateway: Gateway) -> list[str]:
    lines = [f"gateway {cfg.name}: {len(cfg.buses)} buses, {len(gateway.devices)} devices"]
    if cfg.mqtt:
        lines.append(f"  mqtt {cfg.mqtt.host}:{cfg.mqtt.port} prefix {cfg.mqtt.prefix}"
                     + (f", discovery under {cfg.mqtt.discovery_prefix}/" if cfg.mqtt.discovery else ""))
    if cfg.opcua:
        lines.append(f"  opcua {cfg.opcua.endpoint} ({', '.join(cfg.opcua.security)})")
    for line in gateway.lines:
        lines.append(f"  bus {line.name}: {line.cfg.describe()}")
        for dev in line.devices:
            polls = ", ".join(f"{len(p.group.registers)} registers every {p.group.interval:g} s in "
                              f"{len(dev.client.plan([k for a in p.accessors for k in a.keys]))} requests"
                              for p in dev.polls)
            lines.append(f"    {dev.name}: {dev.model.name} unit {dev.cfg.unit}: {polls or 'nothing polled'}")
    return lines


def _check_extras(cfg: GatewayConfig) -> None:
    if cfg.opcua is None:
        return
    try:
        import asyncua  # noqa: F401
    except ImportError:
        where = Location(cfg.path, 1, 1)
        raise CompileError([Diagnostic(where, "opcua needs the optional extra: pip install 'drivemap[opcua]'")]) from None


def run_cli(args: argparse.Namespace, project: Project) -> int:
    """``drivemap gateway``: run until Ctrl-C / SIGTERM (exit 0); configuration errors exit 1."""
    logging.basicConfig(level=args.log_level.upper(), format="%(asctime)s %(levelname)s %(name)s: %(message)s",
                        stream=sys.stderr)
    if args.log_level != "debug":  # asyncua narrates its address space at INFO
        logging.getLogger("asyncua").setLevel(logging.WARNING)
    if args.example:
        sys.stdout.write(example_text())
        return 0
    if args.config is None:
        raise CompileError([Diagnostic(Location("drivemap gateway", 1, 1),
                                       "give CONFIG.yaml (drivemap gateway --example > plant.yaml writes one)")])
    from drivemap.gateway.config import load_config

    broker = parse_broker(args.broker) if args.broker else None
    cfg = load_config(args.config, project, broker=broker)
    _check_extras(cfg)
    _check_endpoint(cfg)
    if args.check:
        asyncio.run(_check(cfg))
        return 0
    asyncio.run(_serve(cfg))
    return 0


def _check_endpoint(cfg: GatewayConfig) -> None:
    """The OPC UA endpoint can be listened on now (the port is free): the error the run would give."""
    if cfg.opcua is None:
        return
    from drivemap.gateway.checks import bind_problem

    problem = bind_problem(cfg.opcua.endpoint)
    if problem is not None:
        raise CompileError([Diagnostic(cfg.opcua.endpoint_at or Location(cfg.path, 1, 1), problem)])


async def _check(cfg: GatewayConfig) -> None:
    from drivemap.gateway.service import Gateway

    for warning in cfg.warnings:
        print(warning.format(), file=sys.stderr)
    print("\n".join(summary(cfg, Gateway(cfg))))


async def _serve(cfg: GatewayConfig) -> None:
    from drivemap.gateway.service import Gateway

    gateway = Gateway(cfg)
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(NotImplementedError, RuntimeError):
            loop.add_signal_handler(sig, stop.set)
    for warning in cfg.warnings:
        print(warning.format(), file=sys.stderr, flush=True)
    print("\n".join(summary(cfg, gateway)), flush=True)
    await gateway.run(stop)
    print(f"gateway {cfg.name} stopped", flush=True)

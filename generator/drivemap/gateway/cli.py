"""``drivemap gateway CONFIG.yaml``: the command line (argparse only at import time; the rest on use)."""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import logging
import signal
import sys
from typing import TYPE_CHECKING

from drivemap.diagnostics import CompileError, Diagnostic, Location

if TYPE_CHECKING:
    from drivemap.frontend.project import Project
    from drivemap.gateway.config import GatewayConfig
    from drivemap.gateway.service import Gateway


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("config", metavar="CONFIG.yaml", help="the gateway configuration")
    parser.add_argument("--check", action="store_true", help="validate the configuration, print what would run, exit")
    parser.add_argument("--log-level", default="info", choices=["debug", "info", "warning", "error"])


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
    from drivemap.gateway.config import load_config

    cfg = load_config(args.config, project)
    _check_extras(cfg)
    if args.check:
        asyncio.run(_check(cfg))
        return 0
    asyncio.run(_serve(cfg))
    return 0


async def _check(cfg: GatewayConfig) -> None:
    from drivemap.gateway.service import Gateway

    print("\n".join(summary(cfg, Gateway(cfg))))


async def _serve(cfg: GatewayConfig) -> None:
    from drivemap.gateway.service import Gateway

    gateway = Gateway(cfg)
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(NotImplementedError, RuntimeError):
            loop.add_signal_handler(sig, stop.set)
    print("\n".join(summary(cfg, gateway)), flush=True)
    await gateway.run(stop)
    print(f"gateway {cfg.name} stopped", flush=True)

"""Why a simulator could not start listening: pymodbus says only "Could not start listen, please
check address."; the message names the address or device and what is wrong with it."""

from __future__ import annotations

import ipaddress
import os
import socket
import termios

__all__ = ["why_not_listening", "is_loopback"]


def why_not_listening(tcp: tuple[str, int] | None, serial: str | None, baudrate: int, exc: Exception) -> str:
    if tcp is not None:
        return f"cannot listen on {tcp[0]}:{tcp[1]} (port in use, or not an address of this host)"
    device = serial or ""
    if not os.path.exists(device):
        return f"no serial device {device}"
    if os.path.isdir(device):
        return f"{device} is a folder, not a serial device"
    try:
        fd = os.open(device, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    except OSError as err:
        return f"cannot open {device}: {err.strerror or err}"
    try:
        termios.tcgetattr(fd)
    except termios.error:
        return f"{device} is not a serial device"
    finally:
        os.close(fd)
    return f"cannot open {device} at {baudrate} Bd ({exc})"


def is_loopback(host: str) -> bool:
    """True when every address ``host`` names is a loopback address."""
    if host in ("localhost", "localhost.localdomain"):
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        pass
    try:
        infos = socket.getaddrinfo(host, None)
    except OSError:
        return False
    return bool(infos) and all(ipaddress.ip_address(str(info[4][0]).split("%")[0]).is_loopback for info in infos)

"""Checks of what a gateway configuration points at: map files, the OPC UA endpoint and serial ports.

Each returns the reason (a sentence for a located error) or None. ``drivemap gateway --check``
and the run make the same checks, so a configuration that passes ``--check`` does not end in a
traceback when it runs.
"""

from __future__ import annotations

import contextlib
import errno
import os
import socket
import stat
from pathlib import Path
from urllib.parse import urlsplit

from drivemap.frontend.project import display

#: Unix98 pseudo-terminal slaves (/dev/pts/N): majors 136-143 on Linux.
_PTY_MAJORS = range(136, 144)


def endpoint_address(endpoint: str) -> tuple[str, int] | str:
    """(host, port) of an ``opc.tcp://HOST:PORT/...`` endpoint, or why it is not one."""
    try:
        parts = urlsplit(endpoint)
        port = parts.port
    except ValueError as exc:
        return f"endpoint {endpoint!r} is not a valid URL ({exc})"
    if parts.scheme != "opc.tcp":
        return f"endpoint {endpoint!r}: the scheme must be opc.tcp://"
    if not parts.hostname:
        return f"endpoint {endpoint!r} names no host (opc.tcp://HOST:PORT/PATH)"
    if port is None or port == 0:
        return f"endpoint {endpoint!r} names no port (opc.tcp://HOST:PORT/PATH; 4840 is OPC UA's)"
    return parts.hostname, port


def endpoint_problem(endpoint: str) -> str | None:
    """Why the server could not listen on ``endpoint`` as written (form and host name), or None."""
    address = endpoint_address(endpoint)
    if isinstance(address, str):
        return address
    host, port = address
    try:
        socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except (OSError, UnicodeError) as exc:
        return f"endpoint {endpoint!r}: host {host!r} does not resolve ({getattr(exc, 'strerror', None) or exc})"
    return None


def bind_problem(endpoint: str) -> str | None:
    """Why the server cannot listen on the endpoint's address now (port in use, address not on this
    host, no permission), or None; binds and closes a socket like asyncio's server does."""
    address = endpoint_address(endpoint)
    if isinstance(address, str):
        return address
    host, port = address
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
    except (OSError, UnicodeError) as exc:
        return f"endpoint {endpoint!r}: host {host!r} does not resolve ({exc})"
    for family, kind, proto, _, sockaddr in infos:
        with socket.socket(family, kind, proto) as sock:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            try:
                sock.bind(sockaddr)
                sock.listen(1)
            except OSError as exc:
                if exc.errno == errno.EADDRINUSE:
                    return f"endpoint {endpoint!r}: port {port} on {host} is already in use"
                return f"endpoint {endpoint!r}: cannot listen on {host}:{port}: {exc.strerror or exc}"
    return None


def map_file_problem(path: Path) -> str | None:
    """Why ``path`` (a device's ``map:``) cannot be read as a map: missing, or not a regular file (a
    device such as /dev/zero, a FIFO, a directory: reading it would never end or block), or None."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        return f"no such map file: {display(path)}"
    except OSError as exc:
        return f"cannot read map file {display(path)}: {exc.strerror}"
    if stat.S_ISREG(st.st_mode):
        return None
    kind = ("a directory" if stat.S_ISDIR(st.st_mode) else "a character device" if stat.S_ISCHR(st.st_mode)
            else "a block device" if stat.S_ISBLK(st.st_mode) else "a FIFO" if stat.S_ISFIFO(st.st_mode)
            else "a socket" if stat.S_ISSOCK(st.st_mode) else "not a regular file")
    return f"map file {display(path)} is {kind}, not a regular file: give the path of a map (.yaml)"


def serial_port_problem(path: Path) -> str | None:
    """Why ``path`` is not a serial device, or None (also None when it does not exist: an adapter
    that is unplugged now is tried again while the gateway runs)."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    if stat.S_ISDIR(st.st_mode):
        return f"serial port {path} is a directory, not a serial device"
    if stat.S_ISREG(st.st_mode):
        return f"serial port {path} is a regular file, not a serial device"
    if stat.S_ISFIFO(st.st_mode) or stat.S_ISSOCK(st.st_mode):
        return f"serial port {path} is a {'FIFO' if stat.S_ISFIFO(st.st_mode) else 'socket'}, not a serial device"
    if stat.S_ISBLK(st.st_mode):
        return f"serial port {path} is a block device, not a serial device"
    major, minor = os.major(st.st_rdev), os.minor(st.st_rdev)
    if major in _PTY_MAJORS:
        return None
    subsystem = Path(f"/sys/dev/char/{major}:{minor}/subsystem")
    with contextlib.suppress(OSError):
        name = os.path.basename(os.readlink(subsystem))
        if name != "tty":
            return (f"serial port {path} is a character device of the kernel's {name!r} subsystem "
                    f"(device {major}:{minor}), not a serial device (a tty)")
    return None


def _read(path: Path) -> tuple[bytes, bool] | str:
    """The bytes of a certificate or key file and whether asyncua reads it as PEM (by the ``.pem``
    suffix, else DER), or why it cannot be read."""
    try:
        return path.read_bytes(), path.suffix.lower() == ".pem"
    except OSError as exc:
        return f"cannot read {display(path)}: {exc.strerror}"


def certificate_problem(path: Path) -> str | None:
    """Why asyncua could not load the X.509 certificate at ``path`` (None: it can, or the opcua extra
    that brings ``cryptography`` is missing, which the command reports on its own)."""
    try:
        from cryptography import x509
    except ImportError:
        return None
    read = _read(path)
    if isinstance(read, str):
        return read
    data, pem = read
    try:
        (x509.load_pem_x509_certificate if pem else x509.load_der_x509_certificate)(data)
    except ValueError:
        return (f"{display(path)} is not an X.509 certificate in {'PEM' if pem else 'DER'} "
                "(asyncua reads PEM from a .pem file, DER from any other)")
    return None


def key_pair_problem(cert: Path, key: Path) -> tuple[str, str] | None:
    """The key (``certificate`` or ``private_key``) and the reason why the server's certificate and
    private key are unusable together, or None."""
    problem = certificate_problem(cert)
    if problem is not None:
        return "certificate", problem
    try:
        from cryptography import x509
        from cryptography.hazmat.primitives import serialization
    except ImportError:
        return None
    read_key, read_cert = _read(key), _read(cert)
    if isinstance(read_key, str):
        return "private_key", read_key
    assert not isinstance(read_cert, str)
    data, pem = read_key
    try:
        private = (serialization.load_pem_private_key if pem else serialization.load_der_private_key)(data, None)
    except TypeError:
        return "private_key", f"{display(key)} is encrypted: the gateway needs an unencrypted private key"
    except ValueError:
        return "private_key", (f"{display(key)} is not a private key in {'PEM' if pem else 'DER'} "
                               "(asyncua reads PEM from a .pem file, DER from any other)")
    certificate = (x509.load_pem_x509_certificate if read_cert[1] else x509.load_der_x509_certificate)(read_cert[0])
    public = serialization.PublicFormat.SubjectPublicKeyInfo
    if private.public_key().public_bytes(serialization.Encoding.DER, public) != \
            certificate.public_key().public_bytes(serialization.Encoding.DER, public):
        return "private_key", f"{display(key)} is not the private key of {display(cert)}"
    return None

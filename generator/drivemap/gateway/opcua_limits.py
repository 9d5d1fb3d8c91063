"""Connection limits of the gateway's OPC UA server (asyncua's binary server, admission added).

``opcua.limits`` in the configuration (defaults in :class:`~drivemap.gateway.config.OpcuaLimits`):

* ``max_connections`` TCP connections at once. A connection past it evicts the oldest
  connection that has no authenticated user (one still in its handshake first, then an anonymous
  session); when every connection belongs to a user, it is refused.
* ``per_source``: connections from one IP address still in their handshake (no session activated
  yet). One more does not refuse the newcomer, whose credentials are not known until it activates
  a session: it closes the oldest handshake from that address, so the connections one host keeps
  silent stay at ``per_source`` and a user who connects and logs in (a handshake takes
  milliseconds) always gets in. Anonymous and user sessions do not count here: an operator is never
  locked out by the anonymous viewers or the half-open connections on the same host (or behind the
  same NAT); anonymous sessions are bounded by ``anonymous_sessions``.
* ``reserve``: the last connections are for users: connections without a user (in handshake or
  anonymous) never hold more than ``max_connections - reserve``; past that the oldest of them is
  closed to make room.
* ``anonymous_sessions``: anonymous sessions at once; one more is refused at activation
  (``BadIdentityTokenRejected``).
* ``handshake_timeout``: seconds a connection may take to activate a session; then it is closed.

asyncua closes a connection whose inbound queue of parsed messages overflows, and its transport
limits bound message and chunk sizes.
"""

from __future__ import annotations

import logging
import time
from typing import Any

from asyncua.crypto.permission_rules import UserRole
from asyncua.server.binary_server_asyncio import BinaryServer, OPCUAProtocol
from asyncua.server.server import Server

from drivemap.gateway.config import OpcuaLimits

log = logging.getLogger("drivemap.gateway.opcua")


def _user_role(protocol: OPCUAProtocol) -> Any:
    """The role of the protocol's activated session, or None (no session, or not activated yet)."""
    processor = protocol.processor
    session = getattr(processor, "session", None) if processor is not None else None
    if session is None or not session.is_activated():
        return None
    return getattr(session.user, "role", None)


class _LimitedProtocol(OPCUAProtocol):
    """One connection, admitted by the limits before asyncua's own processing starts."""

    admission: OpcuaLimits = OpcuaLimits()
    opened: float = 0.0

    def connection_made(self, transport: Any) -> None:
        peer = transport.get_extra_info("peername")
        source = peer[0] if isinstance(peer, tuple) else str(peer)
        self.opened = time.monotonic()
        if not admit(self.clients, source, self.admission):
            log.warning("OPC UA: refusing a connection from %s (%d connections, each with a user session)", source,
                        self.admission.max_connections)
            transport.close()
            return
        super().connection_made(transport)


def _unauthenticated(clients: list[OPCUAProtocol]) -> list[OPCUAProtocol]:
    """Connections without a user's session, oldest first, those still in handshake before the anonymous."""
    pending = [c for c in clients if _user_role(c) is None]
    anonymous = [c for c in clients if _user_role(c) == UserRole.Anonymous]
    key = lambda c: getattr(c, "opened", 0.0)  # noqa: E731
    return sorted(pending, key=key) + sorted(anonymous, key=key)


def _source(c: OPCUAProtocol) -> str:
    peer = c.peer_name
    return str(peer[0] if isinstance(peer, tuple) else peer)


def _close(clients: list[OPCUAProtocol], victim: OPCUAProtocol, why: str) -> None:
    log.warning("OPC UA: closing a connection from %s %s", _source(victim), why)
    if victim.transport is not None:
        victim.transport.close()
    if victim in clients:
        clients.remove(victim)


def admit(clients: list[OPCUAProtocol], source: str, limits: OpcuaLimits) -> bool:
    """Whether a new connection from ``source`` is admitted; closes the connections it displaces (the
    oldest handshake from the same address past ``per_source``; the oldest connections without a
    user past the room they have)."""
    pending = [c for c in _unauthenticated(clients) if _user_role(c) is None and _source(c) == source]
    for victim in pending[:max(0, len(pending) + 1 - limits.per_source)]:
        _close(clients, victim, f"still in its handshake ({limits.per_source} at most from one address)")
    others = _unauthenticated(clients)
    room_for_others = limits.max_connections - limits.reserve
    excess = max(len(others) + 1 - room_for_others, len(clients) + 1 - limits.max_connections, 0)
    if excess > len(others):
        return False
    for victim in others[:excess]:
        _close(clients, victim, "without a user session to make room")
    return True


def anonymous_sessions(clients: list[OPCUAProtocol]) -> int:
    return sum(1 for c in clients if _user_role(c) == UserRole.Anonymous)


class _LimitedBinaryServer(BinaryServer):
    def __init__(self, *args: Any, limits: OpcuaLimits, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.admission = limits

    def _make_protocol(self) -> OPCUAProtocol:
        protocol = _LimitedProtocol(iserver=self.iserver, policies=self._policies, clients=self.clients,
                                    closing_tasks=self.closing_tasks, limits=self.limits)
        protocol.admission = self.admission
        return protocol


class LimitedServer(Server):
    """asyncua's server whose binary server admits connections by :class:`OpcuaLimits`."""

    admission: OpcuaLimits = OpcuaLimits()

    async def start(self) -> None:
        self.iserver.max_connections = self.admission.max_connections + 1  # admission decides first
        self.iserver.max_pending_activation_seconds = self.admission.handshake_timeout
        await self._setup_server_nodes()
        await self.iserver.start()
        try:
            host, port = self._get_bind_socket_info()
            self.bserver = _LimitedBinaryServer(self.iserver, host, port, self.limits, limits=self.admission)
            self.bserver.set_policies(self._policies)
            await self.bserver.start()
        except Exception:
            await self.iserver.stop()
            raise

"""Layer: emulator (asyncio UDP). Imports ``cobot_hmi.enip`` and the emulator's encapsulation
server (whose replies it sends); never the scanner or the service.

Discovery on UDP 44818 (CIP Vol 2 §2-4.2, §2-4.6): ListIdentity, ListServices and ListInterfaces
sent unicast or broadcast are answered as on TCP, with the same reply bytes
(``encap_server.list_reply``). A broadcast ListIdentity is answered after a random delay of
0 to MaxResponseDelay milliseconds, the UINT in the first two bytes of the request's sender
context: 0 means 2000 ms, 1–500 means 500 ms (Vol 2 §2-4.2.1), so a thousand devices do not
answer at the same instant. A unicast request is answered at once. Every other command, and
anything malformed, is dropped without a reply (an unsolicited datagram gets no error back) and
counted.

A socket bound to the emulator's own address receives unicast only; broadcasts reach sockets
bound to the wildcard or to the broadcast address, so the server binds one more socket per
broadcast address it serves (127.255.255.255 on loopback), with ``SO_REUSEADDR`` as every
device on the host does, and always answers from its own address. With the wildcard host one
socket gets everything, and ``IP_PKTINFO`` tells a broadcast (destination ≠ local address)
from a unicast datagram.
"""

from __future__ import annotations

import asyncio
import contextlib
import ipaddress
import logging
import random
import socket
import struct
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Final, Protocol

from cobot_hmi.emulator.counters import TargetCounters
from cobot_hmi.emulator.encap_server import list_reply
from cobot_hmi.enip import encapsulation
from cobot_hmi.enip.cpf import Sockaddr
from cobot_hmi.enip.encapsulation import Command
from cobot_hmi.enip.errors import EnipError
from cobot_hmi.enip.identity import IdentityInfo

log = logging.getLogger(__name__)

IP_PKTINFO: Final = int(getattr(socket, "IP_PKTINFO", 8))
"""Linux's ``IP_PKTINFO`` (Python 3.11 does not export it): each datagram's destination."""
_PKTINFO: Final = struct.Struct("=i4s4s")  # ifindex, local address (spec_dst), header destination

DEFAULT_MAX_DELAY_MS: Final = 2000
"""The reply delay bound when the request's MaxResponseDelay is 0 (CIP Vol 2 §2-4.2.1)."""
MIN_MAX_DELAY_MS: Final = 500
"""A MaxResponseDelay of 1–500 ms is taken as 500 ms (CIP Vol 2 §2-4.2.1)."""
MAX_PENDING_REPLIES: Final = 256
"""Delayed replies held at once; a broadcast flood beyond it is dropped, not queued."""
_READS_PER_WAKEUP: Final = 64
_DISCOVERY_COMMANDS: Final = (Command.LIST_IDENTITY, Command.LIST_SERVICES, Command.LIST_INTERFACES)


def reply_delay_bound_ms(context: bytes) -> int:
    """The longest a ListIdentity reply may wait, from the request's sender context."""
    requested = int.from_bytes(context[:2], "little")
    if requested == 0:
        return DEFAULT_MAX_DELAY_MS
    return max(requested, MIN_MAX_DELAY_MS)


def choose_reply_delay_ms(context: bytes, rng: random.Random) -> float:
    """A new random delay in [0, bound] for each request (CIP Vol 2 §2-4.2.1)."""
    return rng.uniform(0.0, float(reply_delay_bound_ms(context)))


def default_broadcast_hosts(host: str) -> tuple[str, ...]:
    """Which broadcast addresses a server bound to ``host`` listens on besides ``host``."""
    address = ipaddress.IPv4Address(host)
    if address.is_unspecified:
        return ()  # the wildcard socket receives broadcasts itself
    if address.is_loopback:
        return ("127.255.255.255",)
    return ("255.255.255.255",)


class DiscoveryTarget(Protocol):
    """What the discovery server needs of the target (``emulator.target.Target``)."""

    counters: TargetCounters
    identity: IdentityInfo

    def identity_address(self, local_host: str) -> Sockaddr: ...


@dataclass(frozen=True, slots=True)
class ReplyDelay:
    """One delayed ListIdentity reply: who asked, the bound the request allowed and the delay
    chosen."""

    peer: tuple[str, int]
    bound_ms: int
    delay_ms: float


class DiscoveryServer:
    """``await start()`` binds the sockets (an ``OSError`` if the unicast one cannot be bound;
    a broadcast address that cannot be bound is logged and listed in ``broadcast_errors``);
    ``stop()`` closes them and drops the replies still waiting."""

    def __init__(
        self,
        target: DiscoveryTarget,
        host: str,
        port: int = encapsulation.ENIP_TCP_PORT,
        broadcast_hosts: Sequence[str] | None = None,
        *,
        seed: int | None = None,
    ) -> None:
        self.target = target
        self.host = host
        self.port = port
        self.broadcast_hosts = tuple(
            default_broadcast_hosts(host) if broadcast_hosts is None else broadcast_hosts
        )
        self.broadcast_errors: dict[str, str] = {}
        self.recent_delays: deque[ReplyDelay] = deque(maxlen=256)
        """The latest delayed replies (for the status and the tests)."""
        self._rng = random.Random(seed)
        self._sockets: list[socket.socket] = []
        self._unicast: socket.socket | None = None
        self._pending: set[asyncio.TimerHandle] = set()

    @property
    def wildcard(self) -> bool:
        return ipaddress.IPv4Address(self.host).is_unspecified

    async def start(self) -> None:
        loop = asyncio.get_running_loop()
        unicast = self._bind(self.host, self.port)
        self._unicast = unicast
        self.port = unicast.getsockname()[1]
        self._sockets.append(unicast)
        loop.add_reader(unicast.fileno(), self._readable, unicast, False)
        for address in self.broadcast_hosts:
            try:
                sock = self._bind(address, self.port)
            except OSError as error:
                self.broadcast_errors[address] = str(error)
                log.warning("discovery: cannot receive broadcasts to %s: %s", address, error)
                continue
            self._sockets.append(sock)
            loop.add_reader(sock.fileno(), self._readable, sock, True)
        log.info("discovery (UDP) on %s:%d", self.host, self.port)

    def stop(self) -> None:
        for handle in self._pending:
            handle.cancel()
        self._pending.clear()
        loop = asyncio.get_running_loop()
        for sock in self._sockets:
            loop.remove_reader(sock.fileno())
            sock.close()
        self._sockets.clear()
        self._unicast = None

    def status(self) -> dict[str, object]:
        return {
            "host": self.host,
            "port": self.port,
            "broadcast_hosts": list(self.broadcast_hosts),
            "broadcast_errors": dict(self.broadcast_errors),
            "pending_replies": len(self._pending),
        }

    @staticmethod
    def _bind(host: str, port: int) -> socket.socket:
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            # Every EtherNet/IP stack on the host shares UDP 44818 (and its broadcasts).
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_BROADCAST, 1)
            sock.setsockopt(socket.IPPROTO_IP, IP_PKTINFO, 1)
            sock.setblocking(False)
            sock.bind((host, port))
        except OSError:
            sock.close()
            raise
        return sock

    def _readable(self, sock: socket.socket, broadcast_socket: bool) -> None:
        for _ in range(_READS_PER_WAKEUP):
            try:
                data, ancillary, _flags, peer = sock.recvmsg(
                    encapsulation.HEADER_SIZE + 512, socket.CMSG_SPACE(_PKTINFO.size)
                )
            except (BlockingIOError, InterruptedError):
                return
            except OSError as error:  # e.g. an ICMP error queued for an earlier reply
                log.debug("discovery: receive error %s", error)
                continue
            local, destination = self.host, self.host
            for level, kind, value in ancillary:
                if level == socket.IPPROTO_IP and kind == IP_PKTINFO and len(value) >= 12:
                    _index, spec_dst, dst = _PKTINFO.unpack_from(value)
                    local = socket.inet_ntoa(spec_dst)
                    destination = socket.inet_ntoa(dst)
            broadcast = broadcast_socket or destination != local
            if not self.wildcard:
                local = self.host  # we answer from our own address, whatever it reached
            try:
                self._handle(bytes(data), peer, local, broadcast)
            except Exception:  # one bad datagram must not stop the server
                self.target.counters.internal_errors += 1
                log.exception("discovery datagram from %s failed", peer)

    def _handle(self, data: bytes, peer: tuple[str, int], local_host: str, broadcast: bool) -> None:
        counters = self.target.counters
        try:
            message = encapsulation.decode(data)
        except EnipError:
            counters.udp_discovery_ignored += 1
            return
        header = message.header
        if header.command not in _DISCOVERY_COMMANDS or header.options or message.data:
            # Only these commands may come over UDP (CIP Vol 2 §2-3); nothing else is answered.
            counters.udp_discovery_ignored += 1
            return
        reply = list_reply(header, self.target.identity, self.target.identity_address(local_host))
        if reply is None:  # pragma: no cover - the commands above all have a reply
            return
        if header.command == Command.LIST_SERVICES:
            counters.udp_list_services += 1
        elif header.command == Command.LIST_IDENTITY:
            counters.udp_list_identity += 1
            if broadcast:
                if len(self._pending) >= MAX_PENDING_REPLIES:
                    counters.udp_discovery_ignored += 1
                    return
                delay_ms = choose_reply_delay_ms(header.context, self._rng)
                self.recent_delays.append(
                    ReplyDelay(peer, reply_delay_bound_ms(header.context), delay_ms)
                )
                loop = asyncio.get_running_loop()
                handle: asyncio.TimerHandle | None = None

                def send_later() -> None:
                    assert handle is not None
                    self._pending.discard(handle)
                    self._send(reply, peer, local_host)

                handle = loop.call_later(delay_ms / 1e3, send_later)
                self._pending.add(handle)
                return
        self._send(reply, peer, local_host)

    def _send(self, reply: bytes, peer: tuple[str, int], local_host: str) -> None:
        sock = self._unicast
        if sock is None:
            return
        with contextlib.suppress(OSError):  # the asker is gone: nothing to tell anyone
            if self.wildcard:
                # From the address the request reached, not whichever the route prefers: the
                # asker takes the reply's source for the device's address.
                source = _PKTINFO.pack(0, socket.inet_aton(local_host), bytes(4))
                sock.sendmsg([reply], [(socket.IPPROTO_IP, IP_PKTINFO, source)], 0, peer)
            else:
                sock.sendto(reply, peer)

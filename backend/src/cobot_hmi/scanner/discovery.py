"""Layer: scanner (asyncio UDP). Imports ``cobot_hmi.enip``.

Finding EtherNet/IP devices: a ListIdentity request (CIP Vol 2 §2-4.2) over UDP 44818, sent to
each given address and to each given broadcast address, and every ListIdentity reply that comes
back within the timeout, one per answering address. Works with any adapter that answers
ListIdentity over UDP, our emulator included.

The request's sender context carries MaxResponseDelay (its first two bytes, a UINT of
milliseconds; Vol 2 §2-4.2.1): half the timeout, so that devices answering a broadcast spread
their replies over it and all land before it ends. The rest of the context is random and a
reply must echo it, so a stray datagram is not taken for an answer.
"""

from __future__ import annotations

import asyncio
import contextlib
import secrets
import socket
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Final

from cobot_hmi.enip import cpf, encapsulation
from cobot_hmi.enip.cpf import ItemType, Sockaddr
from cobot_hmi.enip.encapsulation import Command, EncapStatus
from cobot_hmi.enip.errors import EnipError
from cobot_hmi.enip.identity import IdentityInfo, decode_list_identity_item

LIMITED_BROADCAST: Final = "255.255.255.255"
MAX_DELAY_LIMIT_MS: Final = 0xFFFF


@dataclass(frozen=True, slots=True)
class DiscoveredDevice:
    """One device's ListIdentity reply: where it came from and what it says."""

    address: str
    """The address the reply came from."""
    identity: IdentityInfo
    announced: Sockaddr
    """The socket address the device announces in its Identity item (its TCP port)."""

    def to_json(self) -> dict[str, object]:
        identity = self.identity
        return {
            "address": self.address,
            "port": self.announced.port,
            "vendor_id": identity.vendor_id,
            "device_type": identity.device_type,
            "product_code": identity.product_code,
            "revision": identity.revision,
            "serial_number": identity.serial_number,
            "serial": f"0x{identity.serial_number:08X}",
            "product_name": identity.product_name,
            "status": identity.status,
            "state": identity.state,
        }


def list_identity_request(max_delay_ms: int, nonce: bytes) -> bytes:
    """A ListIdentity request whose sender context is MaxResponseDelay then 6 bytes of nonce."""
    if not 0 <= max_delay_ms <= MAX_DELAY_LIMIT_MS:
        raise ValueError(f"max delay {max_delay_ms} ms is outside 0–{MAX_DELAY_LIMIT_MS}")
    if len(nonce) != 6:
        raise ValueError("the nonce is 6 bytes")
    context = max_delay_ms.to_bytes(2, "little") + nonce
    return encapsulation.encode(Command.LIST_IDENTITY, context=context)


def parse_list_identity_reply(data: bytes, context: bytes) -> list[tuple[IdentityInfo, Sockaddr]]:
    """The identities in a ListIdentity reply echoing ``context``; ``EnipError`` otherwise."""
    message = encapsulation.decode(data)
    header = message.header
    if header.command != Command.LIST_IDENTITY:
        raise EnipError(f"not a ListIdentity reply (command 0x{header.command:04X})")
    if header.context != context:
        raise EnipError("the reply does not echo our sender context")
    if header.status != EncapStatus.SUCCESS:
        raise EnipError(encapsulation.encap_status_words(header.status))
    return [
        decode_list_identity_item(item.data)
        for item in cpf.decode_items(message.data)
        if item.type_id == ItemType.LIST_IDENTITY
    ]


class _Collector(asyncio.DatagramProtocol):
    def __init__(self, context: bytes, expected: set[str]) -> None:
        self.context = context
        self.expected = expected
        self.devices: dict[str, DiscoveredDevice] = {}
        self.ignored = 0
        self.all_answered = asyncio.Event()

    def datagram_received(self, data: bytes, addr: tuple[str | object, int]) -> None:
        host = str(addr[0])
        try:
            found = parse_list_identity_reply(data, self.context)
        except EnipError:
            self.ignored += 1
            return
        for identity, announced in found:
            self.devices.setdefault(host, DiscoveredDevice(host, identity, announced))
        self.expected.discard(host)
        if not self.expected:
            self.all_answered.set()

    def error_received(self, exc: Exception) -> None:
        pass  # an ICMP "port unreachable" from a host without a device: it just does not answer


@dataclass
class DiscoveryResult:
    devices: list[DiscoveredDevice]
    ignored_datagrams: int


async def discover(
    hosts: Sequence[str] = (),
    broadcast: Sequence[str] = (),
    *,
    timeout_s: float = 2.0,
    port: int = encapsulation.ENIP_TCP_PORT,
    local_host: str = "0.0.0.0",
    max_delay_ms: int | None = None,
    wait_for: Sequence[str] = (),
) -> DiscoveryResult:
    """Ask ``hosts`` (unicast) and ``broadcast`` addresses; wait ``timeout_s`` for the answers:
    no longer than until every unicast host answered when there is no broadcast, or until every
    address in ``wait_for`` answered when given."""
    if max_delay_ms is None:
        max_delay_ms = min(MAX_DELAY_LIMIT_MS, max(1, round(timeout_s * 500)))
    context_nonce = secrets.token_bytes(6)
    request = list_identity_request(max_delay_ms, context_nonce)
    context = request[12:20]
    loop = asyncio.get_running_loop()
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_BROADCAST, 1)
        sock.setblocking(False)
        sock.bind((local_host, 0))
    except OSError:
        sock.close()
        raise
    resolved: list[str] = []
    for host in hosts:
        try:
            infos = await loop.getaddrinfo(
                host, port, family=socket.AF_INET, type=socket.SOCK_DGRAM
            )
        except OSError as error:
            sock.close()
            raise OSError(f"cannot resolve {host}: {error}") from error
        resolved.append(str(infos[0][4][0]))
    # Without a broadcast, done once every host answered; with one, whoever answers in time.
    if wait_for:
        expected = set(wait_for)
    else:
        expected = set(resolved) if resolved and not broadcast else {"\0never"}
    transport, collector = await loop.create_datagram_endpoint(
        lambda: _Collector(context, expected), sock=sock
    )
    try:
        for address in (*resolved, *broadcast):
            try:
                transport.sendto(request, (address, port))
            except OSError as error:
                raise OSError(f"cannot send to {address}:{port}: {error}") from error
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(collector.all_answered.wait(), timeout_s)
    finally:
        transport.close()
    return DiscoveryResult(list(collector.devices.values()), collector.ignored)


__all__ = [
    "LIMITED_BROADCAST",
    "DiscoveredDevice",
    "DiscoveryResult",
    "discover",
    "list_identity_request",
    "parse_list_identity_reply",
]

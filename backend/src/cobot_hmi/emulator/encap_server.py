"""Layer: emulator (asyncio TCP). Imports ``cobot_hmi.enip``.

One encapsulation session per TCP client on port 44818 (CIP Vol 2 §2-3, §2-4):
ListIdentity, ListServices, ListInterfaces, RegisterSession, UnRegisterSession and SendRRData;
SendUnitData is answered with an error (this target has no class 3 connections). A malformed
or unknown message is answered with an encapsulation status and counted; the session goes on.

Bounded so that no client can take the process's file descriptors or memory: at most
``max_tcp_sessions`` connections at once (one more is closed at once and counted), and a message
whose bytes stop coming (a stalled 65,535-byte message, or a connection that sends nothing) is
dropped after ``incomplete_message_timeout_s`` and counted, as is one that does not read its
replies within that time. A registered session may idle between
messages (an originator's session stays open, silent, beside its class 1 connection) up to the
encapsulation inactivity timeout, 120 s by default as the TCP/IP Interface object's attribute
13 (CIP Vol 2 Chapter 5); then it is closed and counted, so registered sessions cannot hold
every place forever either. Class 1 connections live on UDP and go on.

The ListIdentity, ListServices and ListInterfaces replies are built here once, for this TCP
server and the UDP discovery server (``emulator.discovery``) alike (CIP Vol 2 §2-4).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import struct
from typing import Protocol

from cobot_hmi.emulator.counters import TargetCounters
from cobot_hmi.enip import cip, cpf, encapsulation
from cobot_hmi.enip.cpf import CpfItem, ItemType, Sockaddr
from cobot_hmi.enip.encapsulation import Command, EncapHeader, EncapStatus
from cobot_hmi.enip.errors import EnipError
from cobot_hmi.enip.identity import IdentityInfo

log = logging.getLogger(__name__)

_CAPABILITY_CIP_TCP_AND_UDP = 0x0120  # bit 5: CIP over TCP, bit 8: class 0/1 over UDP
_LIST_SERVICES_ITEM_TYPE = 0x0100  # "Communications" service (CIP Vol 2 §2-4.6.3)


def list_reply(header: EncapHeader, identity: IdentityInfo, address: Sockaddr) -> bytes | None:
    """The reply to a ListIdentity, ListServices or ListInterfaces request (CIP Vol 2 §2-4.2,
    §2-4.6, §2-4.3), ``None`` for any other command. ``address`` is what the Identity item
    announces: the address the request reached and the TCP port."""
    command = header.command
    if command == Command.LIST_IDENTITY:
        item = CpfItem(ItemType.LIST_IDENTITY, identity.encode_list_identity_item(address))
        body = cpf.encode_items([item])
    elif command == Command.LIST_SERVICES:
        service = struct.pack("<HH", 1, _CAPABILITY_CIP_TCP_AND_UDP) + b"Communications\x00\x00"
        body = cpf.encode_items([CpfItem(_LIST_SERVICES_ITEM_TYPE, service)])
    elif command == Command.LIST_INTERFACES:
        body = cpf.encode_items([])
    else:
        return None
    return encapsulation.encode(
        command, body, session=header.session, status=EncapStatus.SUCCESS, context=header.context
    )


class SessionLimits(Protocol):
    """The bounds of the TCP server (``TargetSettings``)."""

    @property
    def max_tcp_sessions(self) -> int: ...

    @property
    def incomplete_message_timeout_s(self) -> float: ...

    @property
    def session_inactivity_timeout_s(self) -> float | None: ...


class SessionContext(Protocol):
    """What the CIP layer may ask about the session a request came in on."""

    session_handle: int
    peer_host: str
    local_host: str


class CipHandler(Protocol):
    counters: TargetCounters
    identity: IdentityInfo

    @property
    def settings(self) -> SessionLimits: ...

    def identity_address(self, local_host: str) -> Sockaddr: ...

    def handle_unconnected(
        self, request_data: bytes, items: list[CpfItem], session: SessionContext
    ) -> tuple[bytes, list[CpfItem]]:
        """A Message Router request's bytes → the response's bytes and extra reply items."""
        ...


class EncapSession:
    """One TCP client: reads whole encapsulation messages and answers them in order."""

    _next_handle = 0x1000

    def __init__(
        self,
        handler: CipHandler,
        reader: asyncio.StreamReader,
        writer: asyncio.StreamWriter,
    ) -> None:
        self.handler = handler
        self.reader = reader
        self.writer = writer
        peer = writer.get_extra_info("peername") or ("0.0.0.0", 0)
        local = writer.get_extra_info("sockname") or ("0.0.0.0", 0)
        self.peer_host: str = peer[0]
        self.local_host: str = local[0]
        self.session_handle = 0

    async def run(self) -> None:
        counters = self.handler.counters
        limits = self.handler.settings
        if counters.tcp_connections_open >= limits.max_tcp_sessions:
            counters.tcp_sessions_refused += 1
            self.writer.transport.abort()  # at once, nothing to flush: the descriptor is freed
            return
        counters.tcp_connections_open += 1
        counters.tcp_connections_peak = max(
            counters.tcp_connections_peak, counters.tcp_connections_open
        )
        try:
            while True:
                try:
                    header, data = await self._read_message(limits.incomplete_message_timeout_s)
                except _InactiveError:
                    counters.tcp_sessions_inactive += 1
                    log.info("TCP session from %s closed: inactive", self.peer_host)
                    break
                except TimeoutError:
                    counters.tcp_sessions_timed_out += 1
                    log.info("TCP session from %s dropped: incomplete message", self.peer_host)
                    self.writer.transport.abort()
                    break
                try:
                    reply = self._handle(header, data)
                except Exception:  # never let one bad message end the session
                    counters.internal_errors += 1
                    log.exception("encapsulation command 0x%04X failed", header.command)
                    reply = self._status(header, EncapStatus.INCORRECT_DATA)
                if reply is _CLOSE:
                    break
                if isinstance(reply, bytes):
                    self.writer.write(reply)
                    # A client that asks but never reads must not hold its place forever
                    # either: the reply has to leave within the same timeout.
                    try:
                        async with asyncio.timeout(limits.incomplete_message_timeout_s):
                            await self.writer.drain()
                    except TimeoutError:
                        counters.tcp_sessions_timed_out += 1
                        log.info("TCP session from %s dropped: replies not read", self.peer_host)
                        self.writer.transport.abort()
                        break
        except (asyncio.IncompleteReadError, ConnectionError):
            pass
        finally:
            counters.tcp_connections_open -= 1
            self.writer.close()
            with contextlib.suppress(ConnectionError, OSError):
                await self.writer.wait_closed()

    async def _read_message(self, timeout_s: float) -> tuple[EncapHeader, bytes]:
        """The next whole message. Its bytes must all come within ``timeout_s`` of the first;
        without a registered session, within ``timeout_s`` of the previous reply (or of the
        connection), so a connection that only holds a descriptor is dropped too."""
        reader = self.reader
        head = b""
        if self.session_handle:
            try:
                async with asyncio.timeout(self.handler.settings.session_inactivity_timeout_s):
                    head = await reader.readexactly(1)
            except TimeoutError:
                raise _InactiveError from None
        async with asyncio.timeout(timeout_s):
            head += await reader.readexactly(encapsulation.HEADER_SIZE - len(head))
            header = encapsulation.decode_header(head)
            data = await reader.readexactly(header.length)
        return header, data

    def close(self) -> None:
        self.writer.close()

    # ------------------------------------------------------------------ commands

    def _status(self, header: EncapHeader, status: int, data: bytes = b"") -> bytes:
        return encapsulation.encode(
            header.command, data, session=header.session, status=status, context=header.context
        )

    def _handle(self, header: EncapHeader, data: bytes) -> bytes | object | None:
        counters = self.handler.counters
        command = header.command
        if header.options != 0:
            # The encapsulation spec: a receiver discards a message with non-zero options.
            counters.encapsulation_malformed += 1
            return None
        if command == Command.NOP:
            return None
        if command in (Command.LIST_IDENTITY, Command.LIST_SERVICES, Command.LIST_INTERFACES):
            if data:
                counters.encapsulation_malformed += 1
            address = self.handler.identity_address(self.local_host)
            return list_reply(header, self.handler.identity, address)
        if command == Command.REGISTER_SESSION:
            return self._register(header, data)
        if command == Command.UNREGISTER_SESSION:
            if header.session == self.session_handle and self.session_handle:
                return _CLOSE
            counters.encapsulation_bad_session += 1
            return None
        if command in (Command.SEND_RR_DATA, Command.SEND_UNIT_DATA):
            if not self.session_handle or header.session != self.session_handle:
                counters.encapsulation_bad_session += 1
                return self._status(header, EncapStatus.INVALID_SESSION)
            if command == Command.SEND_UNIT_DATA:
                counters.encapsulation_unsupported += 1
                return self._status(header, EncapStatus.INCORRECT_DATA)
            return self._rr_data(header, data)
        counters.encapsulation_unsupported += 1
        return self._status(header, EncapStatus.INVALID_COMMAND)

    def _register(self, header: EncapHeader, data: bytes) -> bytes:
        counters = self.handler.counters
        try:
            request = encapsulation.decode_register_session(data)
        except EnipError:
            counters.encapsulation_malformed += 1
            return self._status(header, EncapStatus.INVALID_LENGTH)
        if request.protocol_version != encapsulation.PROTOCOL_VERSION or request.options:
            counters.encapsulation_malformed += 1
            return self._status(
                header, EncapStatus.UNSUPPORTED_PROTOCOL, encapsulation.encode_register_session()
            )
        if self.session_handle:
            # One session per TCP connection: a second RegisterSession is an invalid command.
            counters.encapsulation_malformed += 1
            return self._status(header, EncapStatus.INVALID_COMMAND, data)
        EncapSession._next_handle = EncapSession._next_handle % 0x7FFF_FFFF + 1
        self.session_handle = EncapSession._next_handle
        counters.tcp_sessions += 1
        return encapsulation.encode(
            Command.REGISTER_SESSION, data, session=self.session_handle, context=header.context
        )

    def _rr_data(self, header: EncapHeader, data: bytes) -> bytes:
        counters = self.handler.counters
        try:
            _prefix, rest = encapsulation.decode_rr_prefix(data)
            items = cpf.decode_items(rest)
        except EnipError:
            counters.encapsulation_malformed += 1
            return self._status(header, EncapStatus.INCORRECT_DATA)
        if (
            len(items) < 2
            or items[0].type_id != ItemType.NULL_ADDRESS
            or items[0].data
            or items[1].type_id != ItemType.UNCONNECTED_DATA
        ):
            counters.encapsulation_malformed += 1
            return self._status(header, EncapStatus.INCORRECT_DATA)
        try:
            cip.decode_request(items[1].data)
        except EnipError:
            counters.encapsulation_malformed += 1
            return self._status(header, EncapStatus.INCORRECT_DATA)
        counters.explicit_requests += 1
        response, extra = self.handler.handle_unconnected(items[1].data, items[2:], self)
        reply_items = [
            CpfItem(ItemType.NULL_ADDRESS, b""),
            CpfItem(ItemType.UNCONNECTED_DATA, response),
        ]
        body = encapsulation.encode_rr_prefix(0) + cpf.encode_items(reply_items + extra)
        return encapsulation.encode(
            Command.SEND_RR_DATA, body, session=self.session_handle, context=header.context
        )


_CLOSE = object()


class _InactiveError(Exception):
    """A registered session sent nothing for the inactivity timeout."""

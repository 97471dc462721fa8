"""Layer: scanner (asyncio TCP). Imports ``cobot_hmi.enip``.

An encapsulation session from the originator's side (CIP Vol 2 §2-3, docs/protocol.md):
RegisterSession, SendRRData request/response matched by sender context, UnRegisterSession.
The originator uses it for the Forward Open / Forward Close and the explicit read of the O→T
assembly; it runs on the event loop (pycomm3 is blocking, so it cannot).
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
from collections.abc import Sequence

from cobot_hmi.enip import cip, cpf, encapsulation, epath
from cobot_hmi.enip.cip import MessageRouterRequest, MessageRouterResponse, Service
from cobot_hmi.enip.cpf import CpfItem, ItemType
from cobot_hmi.enip.encapsulation import Command, EncapMessage, encap_status_words
from cobot_hmi.enip.errors import EnipError
from cobot_hmi.enip.identity import IdentityInfo, decode_list_identity_item


class SessionError(Exception):
    """The TCP session failed: unreachable, closed, timed out or answered with an
    encapsulation error."""


class EnipSession:
    def __init__(
        self,
        host: str,
        port: int = encapsulation.ENIP_TCP_PORT,
        timeout_s: float = 5.0,
        local_host: str | None = None,
    ) -> None:
        self.host = host
        self.local_host = local_host
        """Source address of the TCP connection: the target sends T→O to it."""
        self.port = port
        self.timeout_s = timeout_s
        self.handle = 0
        self.peer_host: str | None = None
        """The target's address as the TCP connection reached it (its T→O comes from there)."""
        self._reader: asyncio.StreamReader | None = None
        self._writer: asyncio.StreamWriter | None = None
        self._lock = asyncio.Lock()
        self._contexts = itertools.count(1)

    @property
    def is_open(self) -> bool:
        return (
            self._writer is not None
            and not self._writer.is_closing()
            and self._reader is not None
            and not self._reader.at_eof()
        )

    async def open(self) -> None:
        try:
            # asyncio.timeout, not wait_for: on Python 3.11 a wait_for cancelled (the originator
            # stopping) just as the connection came up dropped the connected stream unclosed;
            # in this task, open_connection's own clean-up closes the socket.
            async with asyncio.timeout(self.timeout_s):
                self._reader, self._writer = await asyncio.open_connection(
                    self.host,
                    self.port,
                    local_addr=(self.local_host, 0) if self.local_host else None,
                )
        except (OSError, TimeoutError) as error:
            raise SessionError(f"cannot reach {self.host}:{self.port}: {error}") from None
        peer = self._writer.get_extra_info("peername") if self._writer is not None else None
        self.peer_host = str(peer[0]) if peer else None
        try:
            reply = await self._transact(
                Command.REGISTER_SESSION, encapsulation.encode_register_session()
            )
        except BaseException:  # refused, timed out or cancelled: the socket is not left open
            self.abort()
            raise
        self.handle = reply.header.session

    def abort(self) -> None:
        """Close the socket at once, without unregistering (nothing to await: safe in a
        clean-up that a cancellation may interrupt). Nothing after ``close()``."""
        if self._writer is not None:
            self._writer.transport.abort()
        self._writer = None
        self._reader = None

    async def close(self) -> None:
        writer = self._writer
        if writer is None:
            return
        try:
            if self.handle and not writer.is_closing():
                with contextlib.suppress(OSError):
                    message = encapsulation.encode(Command.UNREGISTER_SESSION, session=self.handle)
                    writer.write(message)
                    await asyncio.wait_for(writer.drain(), self.timeout_s)
        finally:  # a caller's timeout cancelling the drain still closes the socket
            writer.close()
            self._writer = None
            self._reader = None
        with contextlib.suppress(OSError, TimeoutError):
            await asyncio.wait_for(writer.wait_closed(), self.timeout_s)
        self.handle = 0

    async def _transact(self, command: int, data: bytes) -> EncapMessage:
        if self._reader is None or self._writer is None:
            raise SessionError("session not open")
        context = next(self._contexts).to_bytes(8, "little")
        message = encapsulation.encode(command, data, session=self.handle, context=context)
        async with self._lock:
            try:
                self._writer.write(message)
                await asyncio.wait_for(self._writer.drain(), self.timeout_s)
                while True:
                    head = await asyncio.wait_for(
                        self._reader.readexactly(encapsulation.HEADER_SIZE), self.timeout_s
                    )
                    header = encapsulation.decode_header(head)
                    body = await asyncio.wait_for(
                        self._reader.readexactly(header.length), self.timeout_s
                    )
                    if header.context == context and header.command == command:
                        break
            except (OSError, TimeoutError, asyncio.IncompleteReadError) as error:
                raise SessionError(
                    f"session with {self.host}:{self.port} failed: {error or 'timed out'}"
                ) from None
        if header.status:
            raise SessionError(
                f"encapsulation command 0x{command:04X} refused: "
                f"{encap_status_words(header.status)}"
            )
        return EncapMessage(header, body)

    async def request(
        self, request: MessageRouterRequest, extra_items: Sequence[CpfItem] = ()
    ) -> tuple[MessageRouterResponse, list[CpfItem]]:
        """Send one unconnected request; the response and any items after it."""
        items = [
            CpfItem(ItemType.NULL_ADDRESS, b""),
            CpfItem(ItemType.UNCONNECTED_DATA, request.encode()),
            *extra_items,
        ]
        body = encapsulation.encode_rr_prefix(0) + cpf.encode_items(items)
        reply = await self._transact(Command.SEND_RR_DATA, body)
        _prefix, rest = encapsulation.decode_rr_prefix(reply.data)
        reply_items = cpf.decode_items(rest)
        data = cpf.find_item(reply_items, ItemType.UNCONNECTED_DATA)
        if data is None:
            raise EnipError("SendRRData reply without an Unconnected Data item")
        response = cip.decode_response(data.data)
        cip.expect_service(response, request.service)
        return response, [i for i in reply_items if i.type_id not in (0, ItemType.UNCONNECTED_DATA)]

    async def get_attribute_single(
        self, class_id: int, instance: int, attribute: int
    ) -> MessageRouterResponse:
        request = MessageRouterRequest(
            Service.GET_ATTRIBUTE_SINGLE, epath.request_path(class_id, instance, attribute)
        )
        response, _ = await self.request(request)
        return response

    async def list_identity(self) -> IdentityInfo:
        reply = await self._transact(Command.LIST_IDENTITY, b"")
        items = cpf.decode_items(reply.data)
        item = cpf.find_item(items, ItemType.LIST_IDENTITY)
        if item is None:
            raise EnipError("ListIdentity reply without a CIP Identity item")
        return decode_list_identity_item(item.data)[0]

"""Layer: emulator (asyncio I/O). Imports the codec, ``cobot_hmi.enip``, the emulator's own
modules and the runtime support (``udp_endpoint``); never the scanner or the service.

The robot's EtherNet/IP adapter (issue 3, "The target"), composed of one module per CIP object
as the reference C stacks keep them: the encapsulation server on TCP 44818 (``encap_server``),
the Message Router (``objects``) in front of the Identity object (``identity``), the Assembly
object (``assembly``) and the Connection Manager (``connection_manager``), and the class 1 I/O
connections on UDP 2222 (``io_connections``). This module owns their lifecycle and the public
face the tests, the CLI and the control API use.
"""

from __future__ import annotations

import asyncio
import logging
import socket

from cobot_hmi.emulator.assembly import AssemblyObject
from cobot_hmi.emulator.connection_manager import ConnectionManager, RefusalCount
from cobot_hmi.emulator.connections import ConnectionInfo, IoConnection
from cobot_hmi.emulator.counters import TargetCounters
from cobot_hmi.emulator.encap_server import EncapSession, SessionContext
from cobot_hmi.emulator.faults import TargetFaults
from cobot_hmi.emulator.io_connections import (
    HORIZON_MARGIN_S,
    TICK_READ_MAX_RPI_US,
    IoConnections,
)
from cobot_hmi.emulator.objects import MessageRouter
from cobot_hmi.emulator.process_image import ProcessImage
from cobot_hmi.emulator.target_settings import TargetSettings
from cobot_hmi.enip import cip
from cobot_hmi.enip.cpf import CpfItem, Sockaddr
from cobot_hmi.enip.identity import IdentityInfo

log = logging.getLogger(__name__)

ACCEPT_RETRY_DELAY_S = 1.0
"""After a failed accept (no descriptor left), as ``asyncio``'s own server waits."""


class Target:
    """The EtherNet/IP target. ``await start()`` binds the sockets, ``await stop()`` closes
    every connection, session and socket."""

    def __init__(
        self,
        settings: TargetSettings,
        process_image: ProcessImage,
        *,
        faults: TargetFaults | None = None,
    ) -> None:
        self.settings = settings
        self.process_image = process_image
        self.faults = faults if faults is not None else TargetFaults()
        self.counters = TargetCounters()
        self.identity: IdentityInfo = settings.identity
        self._by_o2t: dict[int, IoConnection] = {}
        self._sessions: set[EncapSession] = set()
        self._session_tasks: set[asyncio.Task[None]] = set()
        self._listener: socket.socket | None = None
        self._accepting: asyncio.Task[None] | None = None
        self._stopping = False
        self.assembly = AssemblyObject(
            settings,
            process_image,
            owned=self._owner_present,
            changed=self.process_image_changed,
        )
        self.io = IoConnections(
            settings,
            process_image,
            self.assembly.t2o_data,
            self.assembly.consume_o2t,
            faults=self.faults,
            counters=self.counters,
            table=self._by_o2t,
        )
        self.connection_manager = ConnectionManager(settings, self.faults, self.counters, self.io)
        self.router = MessageRouter(self.identity, self.assembly, self.connection_manager)
        self.tcp_port = settings.tcp_port
        self.udp_port = settings.udp_port

    # ------------------------------------------------------------------ lifecycle

    async def start(self) -> None:
        self._stopping = False
        self.io.start()
        self.udp_port = self.io.udp_port
        try:
            listener = socket.create_server((self.settings.host, self.settings.tcp_port))
        except OSError:
            self.io.shutdown()
            raise
        listener.setblocking(False)
        self._listener = listener
        self.tcp_port = listener.getsockname()[1]
        self._accepting = asyncio.get_running_loop().create_task(self._accept(listener))
        log.info(
            "EtherNet/IP target on %s TCP %d, UDP %d",
            self.settings.host,
            self.tcp_port,
            self.udp_port,
        )

    async def stop(self) -> None:
        self._stopping = True
        self.io.close_all("target stopping")
        if self._accepting is not None:
            self._accepting.cancel()
            await asyncio.gather(self._accepting, return_exceptions=True)
            self._accepting = None
        if self._listener is not None:
            self._listener.close()
            self._listener = None
        await self.drop_sessions()
        self.io.shutdown()

    async def drop_sessions(self) -> None:
        """Close every TCP session (class 1 connections carry on: they live on UDP)."""
        for session in list(self._sessions):
            session.close()
        await asyncio.gather(*self._session_tasks, return_exceptions=True)

    async def _accept(self, listener: socket.socket) -> None:
        """The TCP accept loop. Our own rather than ``asyncio.start_server``: on Python 3.11 a
        ``Server.close()`` that falls between a connection's accept and its transport leaves the
        accepted socket open and owned by no one (the transport's attach to the closed server
        fails). Here an accepted socket is ours from the moment of ``accept()``: the loop waits
        for the listener to be readable (a cancel there loses nothing) and accepts in the same
        step, with no await between (``loop.sock_accept`` would lose a socket accepted just as
        ``stop()`` cancels this loop); a socket caught between accept and transport is closed
        below."""
        loop = asyncio.get_running_loop()
        while True:
            await _readable(loop, listener)
            try:
                connection, _ = listener.accept()
            except (BlockingIOError, InterruptedError):
                continue  # another wake-up took it, or a connection reset in the queue
            except OSError as error:  # out of descriptors
                log.warning("TCP accept failed: %s; accepting again in a second", error)
                await asyncio.sleep(ACCEPT_RETRY_DELAY_S)
                continue
            connection.setblocking(False)
            try:
                await loop.connect_accepted_socket(self._stream_protocol, connection)
            except BaseException:
                connection.close()
                raise

    def _stream_protocol(self) -> asyncio.StreamReaderProtocol:
        return asyncio.StreamReaderProtocol(asyncio.StreamReader(), self._client_connected)

    def _client_connected(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        """Called from the connection's ``connection_made``: the session and its task are known
        at once, so ``stop()`` and ``drop_sessions()`` find a connection whose task has not run
        yet (a coroutine here would start a loop turn later, and a ``stop()`` in between left its
        socket open until the loop ended)."""
        if self._stopping:
            writer.transport.abort()
            return
        session = EncapSession(self, reader, writer)
        self._sessions.add(session)
        task = asyncio.get_running_loop().create_task(self._run_session(session))
        self._session_tasks.add(task)
        task.add_done_callback(self._session_tasks.discard)

    async def _run_session(self, session: EncapSession) -> None:
        try:
            await session.run()
        finally:
            self._sessions.discard(session)

    # ------------------------------------------------------------------ status

    def connections(self) -> list[ConnectionInfo]:
        """A snapshot of every connection (the counts of streamed packets brought up to date,
        in ``counters`` too)."""
        return self.io.connections()

    def pump_counters(self) -> dict[str, int]:
        """The class 1 socket's cyclic pump (``UdpEndpoint.counters``): T→O packets sent and
        send errors, O→T received, its wake-ups, the latest send behind its due time."""
        return self.io.pump_counters()

    def forward_open_refusals(self) -> list[RefusalCount]:
        """Every status a Forward Open was refused with, and how often (docs/emulator.md)."""
        return self.connection_manager.refusals()

    def process_image_changed(self) -> None:
        """The robot changed outside the cycle (a command applied, a control API action): the
        next T→O packet of each connection shows it (``IoConnections.process_image_changed``)."""
        self.io.process_image_changed()

    def _owner_present(self) -> bool:
        return self.io.owner_present()

    # ------------------------------------------------------------------ explicit messages

    def identity_address(self, local_host: str) -> Sockaddr:
        return Sockaddr(local_host, self.tcp_port)

    def handle_unconnected(
        self, request_data: bytes, items: list[CpfItem], session: SessionContext
    ) -> tuple[bytes, list[CpfItem]]:
        request = cip.decode_request(request_data)
        response, extra = self.router.route(request, items, session)
        return response.encode(), extra


async def _readable(loop: asyncio.AbstractEventLoop, sock: socket.socket) -> None:
    """Until ``sock`` is readable (for a listener: a connection waits to be accepted)."""
    ready: asyncio.Future[None] = loop.create_future()

    def wake() -> None:
        if not ready.done():
            ready.set_result(None)

    loop.add_reader(sock.fileno(), wake)
    try:
        await ready
    finally:
        loop.remove_reader(sock.fileno())


__all__ = ["HORIZON_MARGIN_S", "TICK_READ_MAX_RPI_US", "ConnectionInfo", "Target"]

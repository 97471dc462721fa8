"""Layer: scanner. A class 1 connection's lifecycle (:class:`ConnectionLifecycle`): the
supervisor (connect, wait for the loss, teardown, again after a backoff: longer for a target
that refuses), the UDP port (shared, or one of its own), RegisterSession, the explicit read of
the O→T assembly, Forward Open (its reply checked, the T→O connection ID routed on the port to
the T→O receiver, the O→T sender's stream started), the first frame awaited, and Forward
Close + UnRegisterSession at the teardown. The state it reaches goes to the connection's
``ConnectionStatus``.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import random
import socket
import time
from typing import Any

from cobot_hmi.enip import epath
from cobot_hmi.enip.cip import MessageRouterResponse
from cobot_hmi.enip.connection_manager import (
    ConnectionType,
    ForwardCloseRequest,
    ForwardOpenRequest,
    NetworkParams,
    Priority,
    decode_failure_reply,
    decode_forward_open_reply,
)
from cobot_hmi.enip.cpf import CpfItem, ItemType, Sockaddr, decode_sockaddr, sockaddr_item
from cobot_hmi.enip.encapsulation import ENIP_UDP_PORT
from cobot_hmi.enip.errors import EnipError
from cobot_hmi.scanner.connection.link import Link, t2o_batch_s, timeout_s
from cobot_hmi.scanner.connection.o2t_send import O2TSender
from cobot_hmi.scanner.connection.originator_settings import OriginatorSettings, local_address_to
from cobot_hmi.scanner.connection.state import ConnectionState, ConnectionStatus
from cobot_hmi.scanner.connection.t2o_receive import T2OReceiver
from cobot_hmi.scanner.io_port import IoPort
from cobot_hmi.scanner.o2t_stream import O2TStream
from cobot_hmi.scanner.session import EnipSession, SessionError
from cobot_hmi.udp_endpoint import QueueFullError

log = logging.getLogger(__name__)

ORIGINATOR_VENDOR_ID = 0xFFFE
"""Vendor ID in our Forward Opens (a placeholder; part of the connection triplet only)."""


def _forward_open_request(s: OriginatorSettings, link: Link) -> ForwardOpenRequest:
    """The Forward Open of ``link``: both directions point to point at the RPI, the O→T size
    with its run/idle header (or the heartbeat's), the T→O size with its sequence count."""
    o2t_size = s.heartbeat_o2t_size if s.input_only else s.o2t_size + 6
    return ForwardOpenRequest(
        o2t_connection_id=0,
        t2o_connection_id=link.t2o_id,
        connection_serial=link.connection_serial,
        vendor_id=ORIGINATOR_VENDOR_ID,
        originator_serial=link.originator_serial,
        timeout_multiplier=s.timeout_multiplier,
        o2t_rpi_us=s.rpi_us,
        o2t_params=NetworkParams(o2t_size, ConnectionType.POINT_TO_POINT, Priority.SCHEDULED),
        t2o_rpi_us=s.rpi_us,
        t2o_params=NetworkParams(s.t2o_size + 2, ConnectionType.POINT_TO_POINT, Priority.SCHEDULED),
        path=link.path,
        large=s.large_forward_open,
    )


def _o2t_address(target_host: str, items: list[CpfItem]) -> tuple[str, int]:
    """Where O→T goes: the target's UDP 2222, or the address its reply's sockaddr item names."""
    address = (target_host, ENIP_UDP_PORT)
    for item in items:
        if item.type_id == ItemType.SOCKADDR_O2T:
            announced = decode_sockaddr(item.data)
            host = announced.host if announced.host != "0.0.0.0" else target_host
            address = (host, announced.port)
    return address


class _RefusedError(Exception):
    def __init__(self, reason: str, *, opened: bool = False) -> None:
        super().__init__(reason)
        self.reason = reason
        self.opened = opened
        """The target did open the connection (we refuse its reply): close it."""


class ConnectionLifecycle:
    """Connecting, supervising and closing the connection the O→T sender and the T→O receiver
    work on, and the UDP port they use."""

    def __init__(
        self,
        settings: OriginatorSettings,
        status: ConnectionStatus,
        sender: O2TSender,
        receiver: T2OReceiver,
        *,
        io_port: IoPort | None = None,
    ) -> None:
        """``io_port``: the UDP port to share (None: one of our own, opened on start and closed
        on stop)."""
        self.settings = settings
        self._status = status
        self._sender = sender
        self._receiver = receiver
        self._port = io_port
        self._owns_port = io_port is None
        self._rng = random.Random()
        self._session: EnipSession | None = None
        self._supervisor: asyncio.Task[None] | None = None
        self._lost: asyncio.Future[str] | None = None
        self._stopping = False

    @property
    def port(self) -> IoPort | None:
        """The UDP port the connection uses (None before a start without a shared port)."""
        return self._port

    @property
    def owns_port(self) -> bool:
        """The port is the connection's own: every stray datagram on it is ours to count."""
        return self._owns_port

    async def start(self) -> None:
        if self._supervisor is None:
            self._stopping = False
            self._supervisor = asyncio.get_running_loop().create_task(
                self._supervise(), name="originator"
            )

    async def stop(self) -> None:
        self._stopping = True
        task, self._supervisor = self._supervisor, None
        # Cancel until the supervisor has really ended: on Python 3.11 ``asyncio.wait_for`` can
        # swallow a cancellation that lands as its inner awaitable completes (fixed in 3.12),
        # and a single cancel() would then leave stop() waiting for ever.
        while task is not None and not task.done():
            task.cancel()
            await asyncio.wait({task}, timeout=0.5)
        if task is not None and not task.cancelled() and task.exception() is not None:
            log.warning("supervisor ended with %r", task.exception())
        await self._teardown(forward_close=True)
        if self._owns_port and self._port is not None:
            self._port.close()
        self._status.set(ConnectionState.IDLE, None)

    async def _supervise(self) -> None:
        s = self.settings
        status = self._status
        backoff_s = s.backoff_initial_s
        while not self._stopping:
            status.set(ConnectionState.CONNECTING, status.reason)
            try:
                port = await self._open_port()
                await self._connect_once(port)
            except _RefusedError as refused:
                status.set(ConnectionState.REFUSED, refused.reason)
                await self._teardown(forward_close=refused.opened)
            except (OSError, SessionError, EnipError, TimeoutError, QueueFullError) as error:
                status.set(ConnectionState.LOST, str(error) or type(error).__name__)
                await self._teardown(forward_close=True)
            else:
                backoff_s = s.backoff_initial_s
                assert self._lost is not None
                reason = await self._lost
                status.set(ConnectionState.LOST, reason)
                await self._teardown(forward_close=True)
            await asyncio.sleep(backoff_s)
            cap_s = (
                s.refused_backoff_max_s
                if status.state is ConnectionState.REFUSED
                else s.backoff_max_s
            )
            backoff_s = min(backoff_s * 2, cap_s)

    async def _open_port(self) -> IoPort:
        """The shared port (opened on first use), or our own on the local address: the one
        given, or the one that routes to the target."""
        port = self._port
        if port is None:
            s = self.settings
            host = s.local_host
            if host is None:
                host = local_address_to(await self._target_ip())
            port = self._port = IoPort(host, s.udp_port)
        await port.open()
        return port

    async def _target_ip(self) -> str:
        host = self.settings.robot_host
        try:
            infos = await asyncio.get_running_loop().getaddrinfo(
                host, None, family=socket.AF_INET, type=socket.SOCK_DGRAM
            )
        except socket.gaierror as error:
            raise OSError(f"cannot resolve {host}: {error}") from None
        return str(infos[0][4][0])

    async def _connect_once(self, port: IoPort) -> None:
        s = self.settings
        loop = asyncio.get_running_loop()
        session = EnipSession(s.robot_host, s.tcp_port, s.tcp_timeout_s, _source_host(port))
        self._session = session
        await session.open()
        self._sender.adopt_assembly(await self._read_o2t_assembly(session))
        link = Link(
            t2o_id=port.new_connection_id(),
            connection_serial=self._rng.getrandbits(16),
            originator_serial=self._rng.getrandbits(32),
            path=epath.connection_path(
                s.config_instance,
                s.heartbeat_instance if s.input_only else s.o2t_instance,
                s.t2o_instance,
            ),
            target_host=session.peer_host or await self._target_ip(),
            o2t_api_us=s.rpi_us,
            t2o_api_us=s.rpi_us,
            last_rx=loop.time(),
        )
        extra: list[CpfItem] = []
        if s.request_t2o_port is not None:
            extra.append(sockaddr_item(ItemType.SOCKADDR_T2O, Sockaddr("0.0.0.0", port.udp_port)))
        lost: asyncio.Future[str] = loop.create_future()
        first_frame: asyncio.Future[None] = loop.create_future()
        self._lost = lost
        self._sender.attach(link, port)
        self._receiver.attach(link, port, lost=lost, first_frame=first_frame)
        # A point-to-point T→O connection ID is ours (CIP Vol 1 §3-5.4.1): the target may
        # produce on it as soon as it has opened the connection, before we read its reply.
        self._route(port, link, silence_s=0.0)
        response, items = await session.request(_forward_open_request(s, link).request(), extra)
        self._accept_reply(port, link, response)
        link.o2t_addr = _o2t_address(link.target_host, items)
        self._start_o2t(port, link)
        await self._await_first_frame(port, link, first_frame, lost)
        self._status.connected_since = time.time()
        self._status.set(ConnectionState.CONNECTED, None)

    def _accept_reply(self, port: IoPort, link: Link, response: MessageRouterResponse) -> None:
        """The Forward Open's reply: refused, or its connection IDs and granted APIs taken
        (``_RefusedError`` when they cannot be)."""
        s = self.settings
        if not response.ok:
            with contextlib.suppress(EnipError):
                decode_failure_reply(response.data)
            raise _RefusedError(f"Forward Open refused: {response.describe()}")
        reply = decode_forward_open_reply(response.data)
        self._check_api(reply.o2t_api_us or s.rpi_us, reply.t2o_api_us or s.rpi_us)
        if reply.t2o_connection_id != link.t2o_id:
            # Not ours after all (a target choosing it): route the one it produces on.
            port.unroute(link.t2o_id)
            link.routed = False
            link.t2o_id = reply.t2o_connection_id
            try:
                self._route(port, link, silence_s=0.0)
            except ValueError:
                raise _RefusedError(
                    f"Forward Open reply refused: the target produces on T→O connection ID "
                    f"0x{link.t2o_id:08X}, which another connection of this port holds",
                    opened=True,
                ) from None
        link.o2t_id = reply.o2t_connection_id
        link.o2t_api_us = reply.o2t_api_us or s.rpi_us
        link.t2o_api_us = reply.t2o_api_us or s.rpi_us
        self._receiver.granted(link.t2o_api_us)

    def _start_o2t(self, port: IoPort, link: Link) -> None:
        """O→T from now on, at the RPI, built ahead into the cyclic pump (o2t_stream): packets
        the sender builds, the fallback timer the receiver's watchdog."""
        s = self.settings
        sender, receiver = self._sender, self._receiver
        link.o2t = O2TStream(
            port.udp,
            port.new_tag(),
            link.o2t_addr,
            link.o2t_api_us / 1e6,
            lambda: sender.packet(link),
            has_cip_seq=not (s.input_only and s.heartbeat_o2t_size == 0),
            wake_period_s=t2o_batch_s(s),
            on_timer=lambda now, lag_s: receiver.check_silence(link, now, lag_s),
            watchdog_s=timeout_s(link, s),
        )
        link.o2t.start()
        # The pump wakes us once T→O has been silent for the timeout, whatever the batch.
        self._route(port, link, silence_s=timeout_s(link, s))

    async def _await_first_frame(
        self,
        port: IoPort,
        link: Link,
        first_frame: asyncio.Future[None],
        lost: asyncio.Future[str],
    ) -> None:
        first_timeout_s = max(self.settings.first_frame_timeout_s, timeout_s(link, self.settings))
        waits: list[asyncio.Future[Any]] = [first_frame, lost]
        done, _ = await asyncio.wait(
            waits, timeout=first_timeout_s, return_when=asyncio.FIRST_COMPLETED
        )
        if first_frame not in done:
            raise TimeoutError(
                f"no T→O frame within {first_timeout_s:.1f} s of the Forward Open "
                f"(T→O connection 0x{link.t2o_id:08X} on UDP {port.local_host}:{port.udp_port})"
            )

    def _route(self, port: IoPort, link: Link, *, silence_s: float) -> None:
        """T→O of ``link`` from its target goes to the receiver."""
        port.route(
            link.t2o_id,
            link.target_host,
            self._receiver,
            batch_s=t2o_batch_s(self.settings),
            silence_s=silence_s,
            packets_per_s=1e6 / link.t2o_api_us,
        )
        link.routed = True

    def _check_api(self, o2t_api_us: int, t2o_api_us: int) -> None:
        """Refuse a reply granting packet intervals outside the bounds (the connection is open
        on the target's side: the refusal closes it)."""
        s = self.settings
        low_us, high_us = s.api_range_us
        for direction, api_us in (("O→T", o2t_api_us), ("T→O", t2o_api_us)):
            if not low_us <= api_us <= high_us:
                raise _RefusedError(
                    f"Forward Open reply refused: the target grants a {direction} packet "
                    f"interval of {api_us} µs for an RPI of {s.rpi_us} µs (accepted: "
                    f"{low_us}–{high_us} µs)",
                    opened=True,
                )

    async def _read_o2t_assembly(self, session: EnipSession) -> bytes | None:
        """The O→T assembly's data, read explicitly where the target allows it (most refuse
        while another connection owns it) and ``o2t_data`` was not given; None when there is
        nothing to read or the read fails (the O→T sender adopts it)."""
        s = self.settings
        if s.input_only or s.o2t_data is not None:
            return None
        try:
            response = await session.get_attribute_single(epath.CLASS_ASSEMBLY, s.o2t_instance, 3)
        except EnipError:
            return None
        if not response.ok or len(response.data) != s.o2t_size:
            return None
        return bytes(response.data)

    async def _teardown(self, *, forward_close: bool) -> None:
        link = self._receiver.link
        port = self._port
        self._receiver.detach()
        self._sender.detach()
        if link is not None and link.routed and port is not None:
            port.unroute(link.t2o_id)
            link.routed = False
        session, self._session = self._session, None
        try:
            if link is not None and forward_close:
                with contextlib.suppress(SessionError, EnipError, OSError, TimeoutError):
                    await asyncio.wait_for(self._forward_close(session, link), 1.0)
            if session is not None:
                with contextlib.suppress(OSError, TimeoutError):
                    await asyncio.wait_for(session.close(), 1.0)
        finally:
            # stop() cancels a supervisor that may be in here: the session (already out of
            # self._session) must not be left open.
            if session is not None:
                session.abort()
        status = self._status
        if status.state is ConnectionState.CONNECTED and not self._stopping:
            status.set(ConnectionState.LOST, "connection closed")
        self._sender.run = False
        status.connected_since = None

    async def _forward_close(self, session: EnipSession | None, link: Link) -> None:
        s = self.settings
        own = session is None or not session.is_open
        if own:
            source = _source_host(self._port) if self._port is not None else None
            session = EnipSession(s.robot_host, s.tcp_port, 1.0, source)
            await session.open()
        assert session is not None
        try:
            request = ForwardCloseRequest(
                link.connection_serial, ORIGINATOR_VENDOR_ID, link.originator_serial, link.path
            )
            await session.request(request.request())
        finally:
            if own:
                await session.close()


def _source_host(port: IoPort) -> str | None:
    """The TCP session's source address: the target sends T→O to the address our TCP
    connection comes from (docs/operations.md, ports and addresses): the port's address."""
    host = port.local_host
    return None if host in ("0.0.0.0", "") else host

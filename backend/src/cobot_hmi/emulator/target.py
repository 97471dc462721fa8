"""Layer: emulator (asyncio I/O). Imports the codec, ``cobot_hmi.enip``, the emulator's own
modules and the runtime support (``udp_endpoint``); never the scanner or the service.

The robot's EtherNet/IP adapter (issue 3, "The target"): the encapsulation server on TCP 44818
(``encap_server``), the Connection Manager (Forward Open, Large Forward Open, Forward Close),
the explicit objects (``objects``), and the class 1 engine on UDP 2222 (``udp_endpoint``): T→O
packets built ahead on each connection's drift-free RPI schedule and handed to the cyclic pump,
which sends each at its due time; O→T consumed by connection ID (read at our wake-ups while a
connection produces at a short RPI), run/idle applied to the :class:`ProcessImage`, and a
watchdog per connection.
"""

from __future__ import annotations

import asyncio
import logging
import random
import time
from collections.abc import Iterable
from dataclasses import dataclass

from cobot_hmi.codec import CodecError, decode_command, encode_command, encode_frame
from cobot_hmi.emulator.connections import (
    ConnectionKind,
    IoConnection,
    RefusalError,
    admit,
)
from cobot_hmi.emulator.counters import TargetCounters
from cobot_hmi.emulator.encap_server import EncapSession, SessionContext
from cobot_hmi.emulator.faults import TargetFaults
from cobot_hmi.emulator.objects import handle_object_request
from cobot_hmi.emulator.process_image import ProcessImage
from cobot_hmi.emulator.settings import TargetSettings
from cobot_hmi.enip import cip, epath, io
from cobot_hmi.enip.cip import MessageRouterRequest, MessageRouterResponse, Service
from cobot_hmi.enip.connection_manager import (
    ConnectionFailureReply,
    ForwardCloseReply,
    ForwardOpenReply,
    decode_forward_close,
    decode_forward_open,
    decode_unconnected_send,
)
from cobot_hmi.enip.cpf import CpfItem, ItemType, Sockaddr, decode_sockaddr, sockaddr_item
from cobot_hmi.enip.errors import EnipError
from cobot_hmi.enip.identity import IdentityInfo
from cobot_hmi.enip.status import ExtendedStatus, GeneralStatus
from cobot_hmi.udp_endpoint import BATCH_PERIOD_S, QueueFullError, UdpEndpoint

log = logging.getLogger(__name__)

TICK_READ_MAX_RPI_US = round(BATCH_PERIOD_S * 1e6)
"""While a connection produces T→O at a shorter RPI, we wake once per
``TargetSettings.batch_period_s`` (not per packet): each wake-up reads the O→T packets that came
meanwhile (with their kernel receive times) and builds the next batch of T→O packets (or hands
the pump new data for its periodic stream). At this RPI or longer we wake once per packet, and
O→T is read as it arrives."""
HORIZON_MARGIN_S = 0.001
"""How far past the next wake-up T→O is built ahead: a wake-up that comes up to this late still
finds the pump with a packet to send."""


@dataclass(frozen=True, slots=True)
class ConnectionInfo:
    """A snapshot of one class 1 connection, for a status API."""

    o2t_connection_id: int
    t2o_connection_id: int
    kind: str
    peer: str
    """Where T→O goes, ``host:port``."""
    o2t_rpi_us: int
    t2o_rpi_us: int
    timeout_multiplier: int
    run: bool
    packets_in: int
    packets_out: int
    opened_at: float
    o2t_gaps: int = 0
    o2t_duplicates: int = 0
    o2t_intervals: int = 0
    o2t_interval_p50_ms: float | None = None
    o2t_interval_p99_ms: float | None = None
    o2t_interval_max_ms: float | None = None


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
        self._rng = random.Random(settings.seed)
        self._by_o2t: dict[int, IoConnection] = {}
        self._sessions: set[EncapSession] = set()
        self._session_tasks: set[asyncio.Task[None]] = set()
        self._server: asyncio.Server | None = None
        self._udp: UdpEndpoint | None = None
        self._t2o_cache: tuple[object, bytes] | None = None
        self._ticker: asyncio.Handle | None = None
        self._tick_due = 0.0
        self._wake_period_s: float | None = None
        self.tcp_port = settings.tcp_port
        self.udp_port = settings.udp_port

    # ------------------------------------------------------------------ lifecycle

    async def start(self) -> None:
        udp = UdpEndpoint(
            self.settings.host,
            self.settings.udp_port,
            self._o2t_received,
            receive_size=io.MAX_DATAGRAM + 1,
            kernel_timestamps=True,
            on_batch=self._o2t_woke_us,
        )
        udp.watch(True)
        self._udp = udp
        self.udp_port = udp.port
        try:
            self._server = await asyncio.start_server(
                self._client_connected, self.settings.host, self.settings.tcp_port
            )
        except OSError:
            udp.close()
            self._udp = None
            raise
        self.tcp_port = self._server.sockets[0].getsockname()[1]
        log.info(
            "EtherNet/IP target on %s TCP %d, UDP %d",
            self.settings.host,
            self.tcp_port,
            self.udp_port,
        )

    async def stop(self) -> None:
        for conn in list(self._by_o2t.values()):
            self._close(conn, "target stopping", idle=False)
        if self._server is not None:
            self._server.close()
        await self.drop_sessions()
        if self._server is not None:
            await self._server.wait_closed()
            self._server = None
        for conn in self._by_o2t.values():
            conn.cancel_timers()
        if self._ticker is not None:
            self._ticker.cancel()
            self._ticker = None
        if self._udp is not None:
            self._udp.close()
            self._udp = None

    async def drop_sessions(self) -> None:
        """Close every TCP session (class 1 connections carry on: they live on UDP)."""
        for session in list(self._sessions):
            session.close()
        await asyncio.gather(*self._session_tasks, return_exceptions=True)

    def connections(self) -> list[ConnectionInfo]:
        """A snapshot of every connection (the counts of streamed packets brought up to date,
        in ``counters`` too)."""
        self._sync_streamed()
        return [
            ConnectionInfo(
                c.o2t_id,
                c.t2o_id,
                str(c.kind),
                f"{c.peer[0]}:{c.peer[1]}",
                c.o2t_rpi_us,
                c.t2o_rpi_us,
                c.timeout_multiplier,
                c.run,
                c.packets_in,
                c.packets_out,
                c.opened_at,
                c.o2t_gaps,
                c.duplicates,
                *_interval_figures(c.o2t_intervals_ms),
            )
            for c in self._by_o2t.values()
        ]

    def pump_counters(self) -> dict[str, int]:
        """The class 1 socket's cyclic pump (``UdpEndpoint.counters``): T→O packets sent and
        send errors, O→T received, its wake-ups, the latest send behind its due time."""
        return self._udp.counters() if self._udp is not None else {}

    async def _client_connected(
        self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter
    ) -> None:
        session = EncapSession(self, reader, writer)
        self._sessions.add(session)
        task = asyncio.current_task()
        assert task is not None
        self._session_tasks.add(task)
        try:
            await session.run()
        finally:
            self._sessions.discard(session)
            self._session_tasks.discard(task)

    # ------------------------------------------------------------------ explicit messages

    def identity_address(self, local_host: str) -> Sockaddr:
        return Sockaddr(local_host, self.tcp_port)

    def handle_unconnected(
        self, request_data: bytes, items: list[CpfItem], session: SessionContext
    ) -> tuple[bytes, list[CpfItem]]:
        request = cip.decode_request(request_data)
        response, extra = self._dispatch(request, items, session)
        return response.encode(), extra

    def _dispatch(
        self, request: MessageRouterRequest, items: list[CpfItem], session: SessionContext
    ) -> tuple[MessageRouterResponse, list[CpfItem]]:
        if request.path == epath.request_path(epath.CLASS_CONNECTION_MANAGER, 1):
            if request.service in (Service.FORWARD_OPEN, Service.LARGE_FORWARD_OPEN):
                return self._forward_open(request, items, session)
            if request.service == Service.FORWARD_CLOSE:
                return self._forward_close(request), []
            if request.service == Service.UNCONNECTED_SEND:
                try:
                    inner = cip.decode_request(decode_unconnected_send(request.data).message)
                except EnipError:
                    return MessageRouterResponse(
                        request.service,
                        GeneralStatus.CONNECTION_FAILURE,
                        (ExtendedStatus.UNCONNECTED_SEND_PARAMETER_ERROR,),
                    ), []
                # The embedded request's reply stands for the Unconnected Send's (CIP Vol 1
                # 3-5.5.2): this target is the end of the route.
                return self._dispatch(inner, items, session)
            return MessageRouterResponse(request.service, GeneralStatus.SERVICE_NOT_SUPPORTED), []
        return handle_object_request(request, self.identity, self), []

    # AssemblyAccess for ``objects``
    def assembly_instances(self) -> tuple[int, ...]:
        s = self.settings
        return (s.t2o_instance, s.o2t_instance, s.config_instance)

    def assembly_data(self, instance: int) -> bytes:
        if instance == self.settings.t2o_instance:
            return self._t2o_data(time.time())
        if instance == self.settings.o2t_instance:
            return encode_command(self.process_image.command_image())
        return b""

    def set_assembly_data(self, instance: int, data: bytes) -> int:
        if instance != self.settings.o2t_instance:
            if instance == self.settings.config_instance and not data:
                return GeneralStatus.SUCCESS
            return GeneralStatus.ATTRIBUTE_NOT_SETTABLE
        if any(c.kind is ConnectionKind.OWNER for c in self._by_o2t.values()):
            return GeneralStatus.OBJECT_STATE_CONFLICT  # a connection owns the outputs
        if len(data) < self.settings.o2t_size:
            return GeneralStatus.NOT_ENOUGH_DATA
        if len(data) > self.settings.o2t_size:
            return GeneralStatus.TOO_MUCH_DATA
        try:
            image = decode_command(data)
        except CodecError:
            return GeneralStatus.INVALID_ATTRIBUTE_VALUE
        self.process_image.consume_command(image, time.time())
        self.process_image_changed()
        return GeneralStatus.SUCCESS

    # ------------------------------------------------------------------ Connection Manager

    def _forward_open(
        self, request: MessageRouterRequest, items: list[CpfItem], session: SessionContext
    ) -> tuple[MessageRouterResponse, list[CpfItem]]:
        large = request.service == Service.LARGE_FORWARD_OPEN
        self.counters.forward_opens += 1
        try:
            fo = decode_forward_open(request.data, large=large)
        except EnipError:
            self.counters.forward_open_refusals += 1
            return MessageRouterResponse(request.service, GeneralStatus.NOT_ENOUGH_DATA), []

        def refuse(refusal: RefusalError) -> tuple[MessageRouterResponse, list[CpfItem]]:
            self.counters.forward_open_refusals += 1
            failure = ConnectionFailureReply(
                fo.connection_serial, fo.vendor_id, fo.originator_serial
            )
            log.info("Forward Open refused: 0x%04X", refusal.extended)
            return MessageRouterResponse(
                request.service,
                GeneralStatus.CONNECTION_FAILURE,
                refusal.words,
                failure.encode(),
            ), []

        injected = self.faults.refuse_next_forward_open
        if injected is not None:
            self.faults.refuse_next_forward_open = None
            return refuse(RefusalError(injected))
        t2o_port = self.settings.t2o_port_default
        for item in items:
            if item.type_id == ItemType.SOCKADDR_T2O:
                try:
                    t2o_port = decode_sockaddr(item.data).port
                except EnipError:
                    return refuse(RefusalError(ExtendedStatus.INVALID_NETWORK_PARAMETER))
        table = list(self._by_o2t.values())
        try:
            kind = admit(fo, self.settings, table)
        except RefusalError as refusal:
            return refuse(refusal)
        o2t_id = self._new_connection_id()
        t2o_id = fo.t2o_connection_id or self._new_connection_id()
        loop = asyncio.get_running_loop()
        conn = IoConnection(
            kind=kind,
            o2t_id=o2t_id,
            t2o_id=t2o_id,
            triplet=fo.triplet,
            peer=(session.peer_host, t2o_port),
            o2t_rpi_us=fo.o2t_rpi_us,
            t2o_rpi_us=fo.t2o_rpi_us,
            timeout_multiplier=fo.timeout_multiplier,
            o2t_connection_size=fo.o2t_params.size_bytes,
            t2o_connection_size=fo.t2o_params.size_bytes,
            request_path=fo.path,
            opened_at=time.time(),
            last_rx=loop.time(),
        )
        self._by_o2t[o2t_id] = conn
        # The first T→O packet at once (after this reply is written), then every RPI; the
        # watchdog from the open on.
        conn.t2o_last_due = loop.time() - conn.t2o_rpi_us / 1e6
        self._update_schedule()
        log.info(
            "%s connection open: O→T 0x%08X T→O 0x%08X to %s:%d", kind, o2t_id, t2o_id, *conn.peer
        )
        reply = ForwardOpenReply(
            o2t_id,
            t2o_id,
            fo.connection_serial,
            fo.vendor_id,
            fo.originator_serial,
            fo.o2t_rpi_us,
            fo.t2o_rpi_us,
        )
        # Where O→T goes: our UDP port on the address the originator reached us at.
        o2t_item = sockaddr_item(ItemType.SOCKADDR_O2T, Sockaddr(session.local_host, self.udp_port))
        return MessageRouterResponse(request.service, 0, (), reply.encode()), [o2t_item]

    def _new_connection_id(self) -> int:
        while True:
            candidate = self._rng.getrandbits(32)
            if (
                candidate
                and candidate not in self._by_o2t
                and all(c.t2o_id != candidate for c in self._by_o2t.values())
            ):
                return candidate

    def _forward_close(self, request: MessageRouterRequest) -> MessageRouterResponse:
        self.counters.forward_closes += 1
        try:
            fc = decode_forward_close(request.data)
        except EnipError:
            return MessageRouterResponse(request.service, GeneralStatus.NOT_ENOUGH_DATA)
        for conn in list(self._by_o2t.values()):
            if conn.triplet == fc.triplet:
                self._close(conn, "Forward Close")
                reply = ForwardCloseReply(fc.connection_serial, fc.vendor_id, fc.originator_serial)
                return MessageRouterResponse(request.service, 0, (), reply.encode())
        failure = ConnectionFailureReply(fc.connection_serial, fc.vendor_id, fc.originator_serial)
        return MessageRouterResponse(
            request.service,
            GeneralStatus.CONNECTION_FAILURE,
            (ExtendedStatus.CONNECTION_NOT_FOUND,),
            failure.encode(),
        )

    def _close(self, conn: IoConnection, reason: str, *, idle: bool = True) -> None:
        if self._by_o2t.pop(conn.o2t_id, None) is None:
            return
        log.info("%s connection 0x%08X closed: %s", conn.kind, conn.o2t_id, reason)
        if conn.t2o_streaming:
            self._stop_stream(conn)
        conn.cancel_timers()
        if self._udp is not None:
            self._udp.cancel(conn.o2t_id)  # what was built ahead for it does not go out
        self._update_schedule()
        if idle and conn.kind is ConnectionKind.OWNER and conn.run:
            conn.run = False
            self.process_image.outputs_idle(time.time())
            self.process_image_changed()
        if conn.produces and not any(c.produces for c in self._by_o2t.values()):
            # Listen-only connections follow the data they listen to (CIP: 0x0119).
            for other in list(self._by_o2t.values()):
                self._close(other, "the last non-listen-only connection closed", idle=idle)

    # ------------------------------------------------------------------ class 1 engine

    def _update_schedule(self) -> None:
        """The connections changed: how often we wake, and whether O→T wakes us."""
        shortest_us = min((c.t2o_rpi_us for c in self._by_o2t.values()), default=None)
        udp = self._udp
        if self._ticker is not None:
            self._ticker.cancel()
            self._ticker = None
        if shortest_us is None:  # no connection left
            if udp is not None:
                udp.watch(True)
            self._wake_period_s = None
            return
        per_packet = shortest_us >= TICK_READ_MAX_RPI_US
        self._wake_period_s = (
            shortest_us / 1e6
            if per_packet
            else max(shortest_us / 1e6, self.settings.batch_period_s)
        )
        if udp is not None:
            # In batches, the pump wakes us once O→T has been silent for the shortest timeout:
            # a watchdog verdict then comes at once, not at the next batch.
            timeouts = (c.timeout_s for c in self._by_o2t.values())
            udp.watch(per_packet, silence_s=0.0 if per_packet else min(timeouts))
        self._arm_watchdogs()
        self._tick_due = asyncio.get_running_loop().time()
        self._ticker = asyncio.get_running_loop().call_soon(self._tick)

    def _read_due_o2t(self) -> None:
        udp = self._udp
        if udp is not None and not udp.watching:
            udp.drain()

    def _t2o_data(self, now_s: float) -> bytes:
        frame = self.process_image.produce_frame(now_s)
        cache = self._t2o_cache
        if cache is not None and cache[0] is frame:
            return cache[1]
        data = encode_frame(frame)
        size = self.settings.t2o_size
        if len(data) != size:
            data = data[:size].ljust(size, b"\x00")
        self._t2o_cache = (frame, data)
        return data

    def _tick(self) -> None:
        """One wake-up of the class 1 engine: read the O→T that came meanwhile, then build every
        connection's T→O packets up to the next wake-up (plus a margin) and queue them.

        A plain timer callback, not a task. Each packet's frame is computed for the instant it
        is due (the robot model takes the time as an argument), in due order across
        connections, so the model only ever moves forward. The next wake-up is the last queued
        packet's due time (half an RPI before, in batches): at RPIs of ``BATCH_PERIOD_S`` or
        longer, one packet ahead, as a controller prepares the next cycle's data."""
        self._ticker = None
        period_s = self._wake_period_s
        if period_s is None or self._udp is None:
            return
        self._read_due_o2t()
        loop = asyncio.get_running_loop()
        now = loop.time()
        self._judge_batch_watched(now, now - self._tick_due)
        horizon = now + period_s + HORIZON_MARGIN_S
        try:
            self._queue_t2o_until(horizon, now)
        except Exception:  # a robot bug must not stop the connections' heartbeat
            self.counters.internal_errors += 1
            log.exception("T→O production failed")
        if not self._by_o2t:
            return
        queued = [c for c in self._by_o2t.values() if not c.t2o_streaming]
        if not queued:
            self._tick_due = now + period_s  # streams only: the pump needs nothing from us
        else:
            first = min(queued, key=lambda c: c.t2o_last_due)
            wake_at = first.t2o_last_due
            if period_s > first.t2o_rpi_us / 1e6:
                # Batches: wake while the last packet still waits in the pump, so its queue
                # never runs empty (an empty pump would wake for O→T, then for our new batch).
                wake_at -= first.t2o_rpi_us / 2e6
            self._tick_due = max(now + period_s / 2, wake_at)
        self._ticker = loop.call_at(self._tick_due, self._tick)

    def _queue_t2o_until(self, horizon: float, now: float) -> None:
        """Queue each producing connection's packets due up to ``horizon``, earliest first."""
        epoch_minus_loop = time.time() - now
        # A robot whose data refreshes on its own period (the real controller's monitoring
        # values: about every 100 ms) is read once per wake-up, its I/O and state at most one
        # wake-up late; one whose every instant differs, once per packet.
        tick_data = self._t2o_data(now + epoch_minus_loop) if self._reads_per_tick() else None
        stream_data = None if self.faults.per_packet() else tick_data
        for conn in self._by_o2t.values():
            if stream_data is not None:
                self._stream_t2o(conn, stream_data, now)
            elif conn.t2o_streaming:
                self._stop_stream(conn)
        producers = [c for c in self._by_o2t.values() if not c.t2o_streaming]
        while producers:
            conn = min(producers, key=lambda c: c.t2o_last_due + c.t2o_rpi_us / 1e6)
            period_s = conn.t2o_rpi_us / 1e6
            due = conn.t2o_last_due + period_s
            if due > horizon:
                return
            if due < now - period_s:
                due = now  # far behind (a stalled loop): resynchronise, never burst
            conn.t2o_last_due = due
            self._queue_t2o(conn, due, due + epoch_minus_loop, rebuild=False, data=tick_data)

    def _stream_t2o(self, conn: IoConnection, data: bytes, now: float) -> None:
        """T→O of ``conn`` as a periodic stream of the pump carrying ``data``: started after
        the last packet queued (the sequence numbers run on), or given the new data."""
        udp = self._udp
        if udp is None:
            return
        if conn.t2o_streaming:
            if data is not conn.t2o_stream_data:
                udp.replace_periodic(conn.o2t_id, io.encode_io(conn.t2o_id, 0, 0, data))
                conn.t2o_stream_data = data
            return
        period_s = conn.t2o_rpi_us / 1e6
        first_due = max(conn.t2o_last_due + period_s, now - period_s)
        first_seq = (conn.t2o_encap_seq + 1) & 0xFFFFFFFF
        try:
            udp.send_every(
                conn.o2t_id,
                first_due,
                period_s,
                io.encode_io(conn.t2o_id, 0, 0, data),
                conn.peer,
                (io.ENCAP_SEQ_OFFSET, first_seq),
                (io.CIP_SEQ_OFFSET, (conn.t2o_cip_seq + 1) & 0xFFFF),
            )
        except QueueFullError:
            return  # every stream of the pump is taken: this one stays packet by packet
        conn.t2o_streaming = True
        conn.t2o_stream_data = data
        conn.t2o_stream_first_seq = first_seq
        conn.t2o_stream_counted = 0
        conn.t2o_last_kind = "streamed"

    def _count_streamed(self, conn: IoConnection, next_seq: int) -> None:
        sent = (next_seq - conn.t2o_stream_first_seq) & 0xFFFFFFFF
        delta = sent - conn.t2o_stream_counted
        conn.t2o_stream_counted = sent
        conn.packets_out += delta
        self.counters.t2o_sent += delta

    def _stop_stream(self, conn: IoConnection) -> None:
        """Back to packet by packet: the queue goes on where the stream stopped."""
        udp = self._udp
        conn.t2o_streaming = False
        conn.t2o_stream_data = None
        state = udp.stop_periodic(conn.o2t_id) if udp is not None else None
        if state is None:
            return
        next_seq, next_cip, next_due = state
        self._count_streamed(conn, next_seq)
        conn.t2o_encap_seq = (next_seq - 1) & 0xFFFFFFFF
        conn.t2o_cip_seq = (next_cip - 1) & 0xFFFF
        conn.t2o_last_due = next_due - conn.t2o_rpi_us / 1e6
        conn.t2o_last_kind = "none"

    def _sync_streamed(self) -> None:
        udp = self._udp
        if udp is None:
            return
        for conn in self._by_o2t.values():
            if conn.t2o_streaming:
                state = udp.periodic_next(conn.o2t_id)
                if state is not None:
                    self._count_streamed(conn, state[0])

    def _reads_per_tick(self) -> bool:
        return self.process_image.data_period_s > 0

    def _queue_t2o(
        self,
        conn: IoConnection,
        due: float,
        epoch_s: float,
        *,
        rebuild: bool,
        data: bytes | None = None,
    ) -> None:
        """Build the T→O packet due at loop time ``due`` (the frame for ``epoch_s``, unless
        ``data`` is given) and hand it to the pump. ``rebuild``: the packet replaces one taken
        back (same sequence numbers, same fault verdict; the fault draws and counters were made
        when it was first built)."""
        faults = self.faults
        udp = self._udp
        if udp is None:
            return
        if faults.t2o_silent and not rebuild:
            conn.t2o_last_kind = "none"
            return
        if data is None:
            data = self._t2o_data(epoch_s)
        if not rebuild:
            conn.t2o_encap_seq = (conn.t2o_encap_seq + 1) & 0xFFFFFFFF
            conn.t2o_cip_seq = (conn.t2o_cip_seq + 1) & 0xFFFF
        packet = io.encode_io(conn.t2o_id, conn.t2o_encap_seq, conn.t2o_cip_seq, data)
        if rebuild:
            kind = conn.t2o_last_kind
        elif faults.t2o_drop_percent and self._rng.random() * 100.0 < faults.t2o_drop_percent:
            self.counters.t2o_dropped += 1
            kind = "dropped"
        elif faults.t2o_corrupt_count > 0:
            faults.t2o_corrupt_count -= 1
            self.counters.t2o_corrupted += 1
            kind = "corrupt"
        else:
            kind = "sent"
        conn.t2o_last_kind = kind
        if kind == "dropped":
            return
        if kind == "corrupt":
            packet = packet[: len(packet) // 2]  # truncated: the length fields no longer hold
        if not rebuild:
            conn.packets_out += 1
            self.counters.t2o_sent += 1
        udp.send_at(due + faults.t2o_delay_ms / 1e3, packet, conn.peer, conn.o2t_id)

    def process_image_changed(self) -> None:
        """The robot changed outside the cycle (a command applied, a control API action): take
        back each connection's last packet built ahead, if it has not left, and build it again.

        Only the last: the model has moved on to its instant, so earlier packets cannot be
        built again, and they describe instants before the change anyway. At RPIs of
        ``BATCH_PERIOD_S`` or longer the last is the only one: the change is in the next
        packet."""
        udp = self._udp
        if udp is None:
            return
        now = asyncio.get_running_loop().time()
        epoch_minus_loop = time.time() - now
        for conn in self._by_o2t.values():
            if conn.t2o_streaming:
                self._stream_t2o(conn, self._t2o_data(now + epoch_minus_loop), now)
                continue
            if conn.t2o_last_kind not in ("sent", "corrupt"):
                continue
            due = conn.t2o_last_due
            count, _ = udp.cancel(conn.o2t_id, due + self.faults.t2o_delay_ms / 1e3)
            if count:
                self._queue_t2o(conn, due, due + epoch_minus_loop, rebuild=True)

    def _o2t_woke_us(self) -> None:
        """The pump woke us for O→T (read now): per packet, the watchdog timers do the rest; in
        batches this is its word that O→T fell silent, so judge the batch-watched connections."""
        udp = self._udp
        if udp is None or udp.watching:
            return
        self._judge_batch_watched(asyncio.get_running_loop().time(), 0.0)

    def _judge_batch_watched(self, now: float, lag_s: float) -> None:
        """The watchdog verdict of each connection our batch wake-ups watch."""
        for conn in list(self._by_o2t.values()):
            if conn.watchdog is None and self._tick_watches(conn):
                self._watchdog_verdict(conn, now, lag_s)

    def _tick_watches(self, conn: IoConnection) -> bool:
        """Whether our batch wake-ups check this connection's watchdog (no timer of its own):
        while O→T is read at them, if its timeout spans half of one or more. The pump wakes us
        when O→T has been silent for the shortest such timeout, so the verdict is not left to
        the next batch."""
        period_s = self._wake_period_s
        udp = self._udp
        return (
            udp is not None
            and not udp.watching
            and period_s is not None
            and conn.timeout_s >= period_s / 2
        )

    def _arm_watchdogs(self) -> None:
        """A timer for each connection the batch wake-ups do not watch."""
        loop = asyncio.get_running_loop()
        for conn in self._by_o2t.values():
            if conn.watchdog is None and not self._tick_watches(conn):
                deadline = conn.last_rx + conn.timeout_s
                conn.watchdog = loop.call_at(deadline, self._watchdog, conn, deadline)

    def _watchdog(self, conn: IoConnection, armed_for: float) -> None:
        """Armed for the last O→T packet's time + the timeout; re-armed while packets come
        (unless the batch wake-ups took the watch over meanwhile)."""
        conn.watchdog = None
        self._read_due_o2t()
        if self._by_o2t.get(conn.o2t_id) is not conn or self._tick_watches(conn):
            return
        now = asyncio.get_running_loop().time()
        deadline = self._watchdog_verdict(conn, now, now - armed_for)
        if deadline is not None:
            conn.watchdog = asyncio.get_running_loop().call_at(
                deadline, self._watchdog, conn, deadline
            )

    def _watchdog_verdict(self, conn: IoConnection, now: float, lag_s: float) -> float | None:
        """Close the connection if no O→T came for its timeout; else when to look again.

        Looking more than an O→T RPI late, the loop itself stalled (a busy machine) and O→T
        packets may be waiting, unread: the verdict waits one more RPI, after the loop has read
        its sockets again."""
        timeout_s = conn.timeout_s
        deadline = conn.last_rx + timeout_s
        rpi_s = conn.o2t_rpi_us / 1e6
        if lag_s > rpi_s:
            deadline = max(deadline, now + rpi_s)
        if now < deadline:
            return deadline
        self.counters.watchdog_timeouts += 1
        self._close(conn, f"watchdog: no O→T for {timeout_s * 1e3:.0f} ms (0x0203)")
        return None

    def _o2t_received(self, data: bytes, addr: tuple[str, int], arrived: float) -> None:
        """One O→T datagram, ``arrived`` at that loop time (the kernel's receive time)."""
        counters = self.counters
        try:
            packet = io.decode_io(data)
        except EnipError:
            counters.udp_malformed += 1
            return
        conn = self._by_o2t.get(packet.connection_id)
        if conn is None or addr[0] != conn.peer[0]:
            counters.udp_unknown_connection += 1
            return
        last = conn.last_o2t_encap_seq
        if last is not None and io.seq32_newer(packet.encap_seq, last) <= 0:
            counters.udp_stale += 1
            return
        if conn.kind is not ConnectionKind.OWNER:
            conn.last_o2t_encap_seq = packet.encap_seq
            conn.last_rx = max(conn.last_rx, arrived)
            conn.packets_in += 1
            return
        payload = packet.payload
        if packet.cip_seq is None or len(payload) != self.settings.o2t_size + 4:
            counters.udp_malformed += 1
            return
        conn.last_o2t_encap_seq = packet.encap_seq
        conn.last_rx = max(conn.last_rx, arrived)
        conn.packets_in += 1
        if packet.cip_seq == conn.last_o2t_cip_seq:
            conn.duplicates += 1
            counters.udp_duplicates += 1
            return  # the same sequence count: no new data
        last_cip = conn.last_o2t_cip_seq
        if last_cip is not None:
            ahead = io.seq16_newer(packet.cip_seq, last_cip)
            if ahead > 1:
                conn.o2t_gaps += ahead - 1
        conn.last_o2t_cip_seq = packet.cip_seq
        now = conn.last_rx
        if conn.last_o2t_at is not None:
            conn.o2t_intervals_ms.append((now - conn.last_o2t_at) * 1e3)
        conn.last_o2t_at = now
        run, command = io.split_run_idle(payload)
        if run:
            conn.run = True
            if command != conn.last_applied:
                conn.last_applied = command
                self.process_image.consume_command(decode_command(command), time.time())
                self.process_image_changed()
        elif conn.run:
            conn.run = False
            conn.last_applied = None
            self.process_image.outputs_idle(time.time())
            self.process_image_changed()


def _interval_figures(
    intervals_ms: Iterable[float],
) -> tuple[int, float | None, float | None, float | None]:
    values = sorted(intervals_ms)
    n = len(values)
    if not n:
        return 0, None, None, None
    return n, values[n // 2], values[min(n - 1, int(n * 0.99))], values[-1]


__all__ = ["ConnectionInfo", "Target"]

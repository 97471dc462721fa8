"""Layer: scanner (asyncio I/O, the originator role). Imports the codec, ``cobot_hmi.enip``, the
scanner's own modules and the runtime support (``udp_endpoint``); never the emulator or the
service.

The backend's class 1 connection to the robot, held as a PLC holds it (issue 3, "The
originator"): RegisterSession, Forward Open (exclusive owner, or input-only as a read-only
mode), T→O received on UDP 2222 of the local address, O→T sent from the same socket at the RPI
on a drift-free schedule with the run/idle header (``o2t_stream``: built ahead, sent by the cyclic
pump), a watchdog on T→O silence, reconnection with backoff, and Forward Close +
UnRegisterSession on shutdown.

Bumpless takeover: every connection starts **idle**, and its command image is seeded from the
robot's actual outputs in the first T→O frame (and the bit input registers from an explicit
read of the O→T assembly where the target allows it), so switching to run changes nothing
until someone writes. The state is CONNECTED only once that first frame has arrived.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import random
import time
from collections.abc import Callable
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

from cobot_hmi.codec import (
    O2T_SIZE,
    T2O_SIZE,
    CodecError,
    CommandImage,
    Frame,
    decode_command,
    decode_frame,
    encode_command,
    zero_command,
)
from cobot_hmi.enip import epath, io
from cobot_hmi.enip.connection_manager import (
    ConnectionType,
    ForwardCloseRequest,
    ForwardOpenRequest,
    NetworkParams,
    Priority,
    connection_timeout_us,
    decode_failure_reply,
    decode_forward_open_reply,
)
from cobot_hmi.enip.cpf import CpfItem, ItemType, Sockaddr, decode_sockaddr, sockaddr_item
from cobot_hmi.enip.encapsulation import ENIP_TCP_PORT, ENIP_UDP_PORT
from cobot_hmi.enip.errors import EnipError
from cobot_hmi.layout import CONNECTION_POINTS
from cobot_hmi.scanner.o2t_stream import O2TStream
from cobot_hmi.scanner.session import EnipSession, SessionError
from cobot_hmi.scanner.stats import IntervalWindow
from cobot_hmi.udp_endpoint import BATCH_PERIOD_S, UdpEndpoint

log = logging.getLogger(__name__)

ORIGINATOR_VENDOR_ID = 0xFFFE
"""Vendor ID in our Forward Opens (a placeholder; part of the connection triplet only)."""


class ConnectionState(StrEnum):
    IDLE = "idle"
    CONNECTING = "connecting"
    CONNECTED = "connected"
    LOST = "lost"
    REFUSED = "refused"


class ReadOnlyError(Exception):
    """The originator is input-only: it never owns the robot's outputs."""


class NotConnectedError(Exception):
    """No class 1 connection is up."""


@dataclass(frozen=True)
class OriginatorSettings:
    robot_host: str
    tcp_port: int = ENIP_TCP_PORT
    local_host: str = "0.0.0.0"
    local_udp_port: int = ENIP_UDP_PORT
    rpi_us: int = 10_000
    timeout_multiplier: int = 2
    """Connection timeout = RPI × (4 << multiplier): 2 → RPI × 16."""
    input_only: bool = False
    large_forward_open: bool = False
    config_instance: int = CONNECTION_POINTS.configuration
    o2t_instance: int = CONNECTION_POINTS.o2t
    t2o_instance: int = CONNECTION_POINTS.t2o
    heartbeat_instance: int = CONNECTION_POINTS.input_only
    o2t_size: int = O2T_SIZE
    t2o_size: int = T2O_SIZE
    request_t2o_port: int | None = None
    """Ask for T→O on this local port (a Sockaddr Info 0x8001 item) instead of 2222."""
    heartbeat_o2t_size: int = 0
    """O→T connection size of an input-only connection (targets accept 0, 2 or 6)."""
    backoff_initial_s: float = 0.1
    backoff_max_s: float = 5.0
    tcp_timeout_s: float = 5.0
    first_frame_timeout_s: float = 2.0
    """How long after a Forward Open the first T→O frame may take (at least the watchdog)."""
    t2o_batch_s: float = 0.040
    """At RPIs shorter than ``BATCH_PERIOD_S`` (10 ms), how often we wake for T→O at most: the
    frames of each batch are read together, each with the kernel's receive time. Neither O→T
    (a change goes into the next packet at once) nor the watchdog (the pump reports silence)
    waits for it."""

    @property
    def udp_port(self) -> int:
        return self.request_t2o_port if self.request_t2o_port is not None else self.local_udp_port


@dataclass(frozen=True)
class ConnectionStats:
    state: ConnectionState
    reason: str | None
    packets_in: int
    packets_out: int
    gaps: int
    """T→O packets missing (CIP sequence count jumps), summed."""
    duplicates: int
    """T→O packets repeating the last CIP sequence count (no new data)."""
    late: int
    """T→O frames that came more than 1.5 RPI after the previous one."""
    malformed: int
    interval_mean_ms: float | None
    interval_p99_ms: float | None
    interval_max_ms: float | None
    last_frame_age_s: float | None
    connected_since: float | None
    """Epoch seconds."""
    stale: int = 0
    """T→O packets older than one already received (out of order), dropped."""
    foreign: int = 0
    """Datagrams for another connection ID, dropped."""
    frames: int = 0
    interval_p50_ms: float | None = None
    rpi_us: int | None = None
    """The T→O actual packet interval of the connection (the target's reply)."""


class _RefusedError(Exception):
    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


@dataclass
class _Link:
    """One Forward Open's worth of negotiated parameters and sequence state."""

    o2t_id: int
    t2o_id: int
    connection_serial: int
    originator_serial: int
    o2t_api_us: int
    t2o_api_us: int
    o2t_addr: tuple[str, int]
    path: bytes
    last_t2o_encap_seq: int | None = None
    last_t2o_cip_seq: int | None = None
    last_frame_at: float | None = None
    """Loop time of the last new frame."""
    last_rx: float = 0.0
    """Loop time the kernel received the last accepted T→O packet."""
    last_payload: tuple[bytes, Frame] | None = None
    """The last T→O payload decoded, and its frame."""
    o2t: O2TStream | None = None


class Originator:
    def __init__(
        self,
        settings: OriginatorSettings,
        *,
        on_frame: Callable[[Frame, float, int], None] | None = None,
        on_state: Callable[[ConnectionState, str | None], None] | None = None,
    ) -> None:
        self.settings = settings
        self.on_frame = on_frame
        self.on_state = on_state
        self.state = ConnectionState.IDLE
        self.reason: str | None = None
        self.latest: tuple[Frame, float] | None = None
        self.run = False
        self.command: CommandImage = zero_command()
        self._command_bytes = encode_command(self.command)
        self._rng = random.Random()
        self._udp: UdpEndpoint | None = None
        self._session: EnipSession | None = None
        self._link: _Link | None = None
        self._supervisor: asyncio.Task[None] | None = None
        self._lost: asyncio.Future[str] | None = None
        self._first_frame: asyncio.Future[None] | None = None
        self._connected_event = asyncio.Event()
        self._explicit_bits: tuple[bool, ...] | None = None
        self._seeded = False
        self._stopping = False
        self._window = IntervalWindow()
        self._connected_since: float | None = None
        self.packets_in = 0
        self._packets_out_closed = 0
        """O→T packets sent by endpoints closed since (a stop and a start)."""
        self.gaps = 0
        self.duplicates = 0
        self.late = 0
        self.malformed = 0
        self.stale = 0
        self.foreign = 0
        self.frames = 0

    # ------------------------------------------------------------------ public interface

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
        if self._udp is not None:
            self._packets_out_closed += self._udp.counters()["sent"]
            self._udp.close()
            self._udp = None
        self._set_state(ConnectionState.IDLE, None)

    def stats(self) -> ConnectionStats:
        figures = self._window.figures()
        latest = self.latest
        link = self._link
        return ConnectionStats(
            state=self.state,
            reason=self.reason,
            packets_in=self.packets_in,
            packets_out=self.packets_out,
            gaps=self.gaps,
            duplicates=self.duplicates,
            late=self.late,
            malformed=self.malformed,
            interval_mean_ms=figures.mean_ms,
            interval_p99_ms=figures.p99_ms,
            interval_max_ms=figures.max_ms,
            last_frame_age_s=time.time() - latest[1] if latest is not None else None,
            connected_since=self._connected_since,
            stale=self.stale,
            foreign=self.foreign,
            frames=self.frames,
            interval_p50_ms=figures.p50_ms,
            rpi_us=link.t2o_api_us if link is not None else None,
        )

    @property
    def packets_out(self) -> int:
        """O→T packets that left (counted by the cyclic pump as it sends them)."""
        udp = self._udp
        return self._packets_out_closed + (udp.counters()["sent"] if udp is not None else 0)

    def pump_counters(self) -> dict[str, int]:
        """The cyclic pump's counters (``UdpEndpoint.counters``), zeros without an endpoint."""
        udp = self._udp
        return udp.counters() if udp is not None else {}

    def set_run(self, run: bool) -> None:
        if self.settings.input_only:
            raise ReadOnlyError("input-only connection: the outputs belong to another owner")
        if self.state is not ConnectionState.CONNECTED:
            raise NotConnectedError(f"not connected ({self.state}: {self.reason or 'no reason'})")
        if run != self.run:
            self.run = run
            self._rebuild_o2t()

    def set_command(self, image: CommandImage) -> int:
        """Put ``image`` on the wire; returns the ``packets_out`` count after which it has
        gone out (see :meth:`wait_sent`)."""
        self.command = image
        self._command_bytes = encode_command(image)
        # Every packet not sent yet is built again with the image: the next one out has it.
        self._rebuild_o2t()
        return self.packets_out + 1

    def _rebuild_o2t(self) -> None:
        link = self._link
        if link is not None and link.o2t is not None:
            link.o2t.rebuild()

    async def wait_sent(self, packets_out: int, timeout_s: float) -> bool:
        """Whether ``packets_out`` O→T packets have left within ``timeout_s``. The pump sends
        without waking us, so this looks again every half RPI (only while someone waits)."""
        loop = asyncio.get_running_loop()
        end = loop.time() + timeout_s
        link = self._link
        step_s = max(0.001, (link.o2t_api_us if link is not None else 10_000) / 2e6)
        while self.packets_out < packets_out:
            if loop.time() >= end:
                return False
            await asyncio.sleep(min(step_s, max(0.0, end - loop.time())))
        return True

    async def wait_connected(self, timeout_s: float) -> bool:
        if self.state is ConnectionState.CONNECTED:
            return True
        try:
            await asyncio.wait_for(self._connected_event.wait(), timeout_s)
        except TimeoutError:
            return False
        state: ConnectionState = self.state  # changed by the supervisor meanwhile
        return state is ConnectionState.CONNECTED

    # ------------------------------------------------------------------ supervision

    def _set_state(self, state: ConnectionState, reason: str | None) -> None:
        if state is self.state and reason == self.reason:
            return
        self.state = state
        self.reason = reason
        if state is ConnectionState.CONNECTED:
            self._connected_event.set()
        else:
            self._connected_event.clear()
        if reason:
            log.info("originator %s: %s", state, reason)
        if self.on_state is not None:
            try:
                self.on_state(state, reason)
            except Exception:
                log.exception("on_state callback failed")

    async def _supervise(self) -> None:
        s = self.settings
        backoff_s = s.backoff_initial_s
        while not self._stopping:
            self._set_state(ConnectionState.CONNECTING, self.reason)
            try:
                await self._ensure_udp()
                await self._connect_once()
            except _RefusedError as refused:
                self._set_state(ConnectionState.REFUSED, refused.reason)
                await self._teardown(forward_close=False)
            except (OSError, SessionError, EnipError, TimeoutError) as error:
                self._set_state(ConnectionState.LOST, str(error) or type(error).__name__)
                await self._teardown(forward_close=True)
            else:
                backoff_s = s.backoff_initial_s
                assert self._lost is not None
                reason = await self._lost
                self._set_state(ConnectionState.LOST, reason)
                await self._teardown(forward_close=True)
            await asyncio.sleep(backoff_s)
            backoff_s = min(backoff_s * 2, s.backoff_max_s)

    async def _ensure_udp(self) -> None:
        if self._udp is not None:
            return
        s = self.settings
        try:
            udp = UdpEndpoint(
                s.local_host,
                s.udp_port,
                self._t2o_received,
                receive_size=io.MAX_DATAGRAM + 1,
                on_batch=self._t2o_batch_read,
            )
        except OSError as error:
            raise OSError(f"cannot bind UDP {s.local_host}:{s.udp_port}: {error}") from None
        # T→O wakes us as it comes, or once per batch at RPIs shorter than the batch period
        # (each packet keeps the kernel's receive time either way).
        udp.watch(True, self._t2o_batch_s)
        self._udp = udp

    async def _connect_once(self) -> None:
        s = self.settings
        loop = asyncio.get_running_loop()
        session = EnipSession(s.robot_host, s.tcp_port, s.tcp_timeout_s, self._source_host)
        self._session = session
        await session.open()
        self._explicit_bits = await self._read_o2t_bits(session)

        connection_serial = self._rng.getrandbits(16)
        originator_serial = self._rng.getrandbits(32)
        t2o_id = self._rng.getrandbits(32) or 1
        o2t_point = s.heartbeat_instance if s.input_only else s.o2t_instance
        o2t_size = s.heartbeat_o2t_size if s.input_only else s.o2t_size + 6
        path = epath.connection_path(s.config_instance, o2t_point, s.t2o_instance)
        request = ForwardOpenRequest(
            o2t_connection_id=0,
            t2o_connection_id=t2o_id,
            connection_serial=connection_serial,
            vendor_id=ORIGINATOR_VENDOR_ID,
            originator_serial=originator_serial,
            timeout_multiplier=s.timeout_multiplier,
            o2t_rpi_us=s.rpi_us,
            o2t_params=NetworkParams(o2t_size, ConnectionType.POINT_TO_POINT, Priority.SCHEDULED),
            t2o_rpi_us=s.rpi_us,
            t2o_params=NetworkParams(
                s.t2o_size + 2, ConnectionType.POINT_TO_POINT, Priority.SCHEDULED
            ),
            path=path,
            large=s.large_forward_open,
        )
        extra: list[CpfItem] = []
        if s.request_t2o_port is not None:
            extra.append(sockaddr_item(ItemType.SOCKADDR_T2O, Sockaddr("0.0.0.0", s.udp_port)))
        response, items = await session.request(request.request(), extra)
        if not response.ok:
            with contextlib.suppress(EnipError):
                decode_failure_reply(response.data)
            raise _RefusedError(f"Forward Open refused: {response.describe()}")
        reply = decode_forward_open_reply(response.data)
        o2t_addr = (s.robot_host, ENIP_UDP_PORT)
        for item in items:
            if item.type_id == ItemType.SOCKADDR_O2T:
                announced = decode_sockaddr(item.data)
                host = announced.host if announced.host != "0.0.0.0" else s.robot_host
                o2t_addr = (host, announced.port)
        self._link = _Link(
            o2t_id=reply.o2t_connection_id,
            t2o_id=reply.t2o_connection_id,
            connection_serial=connection_serial,
            originator_serial=originator_serial,
            o2t_api_us=reply.o2t_api_us or s.rpi_us,
            t2o_api_us=reply.t2o_api_us or s.rpi_us,
            o2t_addr=o2t_addr,
            path=path,
            last_rx=loop.time(),
        )
        self.run = False
        self._seeded = False
        self._window.clear()
        self._lost = loop.create_future()
        self._first_frame = loop.create_future()
        link = self._link
        assert self._udp is not None
        # O→T from now on, at the RPI, built ahead into the cyclic pump (o2t_stream).
        link.o2t = O2TStream(
            self._udp,
            link.o2t_id,
            link.o2t_addr,
            link.o2t_api_us / 1e6,
            lambda: self._o2t_packet(link),
            has_cip_seq=not (s.input_only and s.heartbeat_o2t_size == 0),
            wake_period_s=self._t2o_batch_s,
            on_timer=lambda now, lag_s: self._check_t2o_silence(link, now, lag_s),
        )
        link.o2t.start()
        # The pump wakes us once T→O has been silent for the timeout, whatever the batch.
        self._udp.watch(True, self._t2o_batch_s, silence_s=self._timeout_s(link))
        first_timeout_s = max(s.first_frame_timeout_s, self._timeout_s(self._link))
        waits: list[asyncio.Future[Any]] = [self._first_frame, self._lost]
        done, _ = await asyncio.wait(
            waits, timeout=first_timeout_s, return_when=asyncio.FIRST_COMPLETED
        )
        if self._first_frame not in done:
            raise TimeoutError(
                f"no T→O frame within {first_timeout_s:.1f} s of the Forward Open "
                f"(T→O connection 0x{self._link.t2o_id:08X} on UDP {s.udp_port})"
            )
        self._connected_since = time.time()
        self._set_state(ConnectionState.CONNECTED, None)

    async def _read_o2t_bits(self, session: EnipSession) -> tuple[bool, ...] | None:
        """The bit input registers from an explicit read of the O→T assembly, if allowed."""
        s = self.settings
        try:
            response = await session.get_attribute_single(epath.CLASS_ASSEMBLY, s.o2t_instance, 3)
        except EnipError:
            return None
        if not response.ok or len(response.data) != s.o2t_size:
            return None
        try:
            return decode_command(response.data).bit_input_registers
        except CodecError:
            return None

    @property
    def _source_host(self) -> str | None:
        # The target sends T→O to the address our TCP connection comes from (ethernetip.md
        # "Two stacks on one host"): it must be the address we receive UDP on.
        host = self.settings.local_host
        return None if host in ("0.0.0.0", "") else host

    @property
    def _t2o_batch_s(self) -> float:
        s = self.settings
        return s.t2o_batch_s if s.rpi_us < BATCH_PERIOD_S * 1e6 else 0.0

    def _timeout_s(self, link: _Link) -> float:
        return connection_timeout_us(link.t2o_api_us, self.settings.timeout_multiplier) / 1e6

    async def _teardown(self, *, forward_close: bool) -> None:
        link, self._link = self._link, None
        if link is not None and link.o2t is not None:
            link.o2t.stop()
        for future in (self._lost, self._first_frame):
            if future is not None and not future.done():
                future.cancel()
        session, self._session = self._session, None
        if link is not None and forward_close:
            with contextlib.suppress(SessionError, EnipError, OSError, TimeoutError):
                await asyncio.wait_for(self._forward_close(session, link), 1.0)
        if session is not None:
            with contextlib.suppress(OSError, TimeoutError):
                await asyncio.wait_for(session.close(), 1.0)
        if self.state is ConnectionState.CONNECTED and not self._stopping:
            self._set_state(ConnectionState.LOST, "connection closed")
        self.run = False
        self._connected_since = None

    async def _forward_close(self, session: EnipSession | None, link: _Link) -> None:
        s = self.settings
        own = session is None or not session.is_open
        if own:
            session = EnipSession(s.robot_host, s.tcp_port, 1.0, self._source_host)
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

    # ------------------------------------------------------------------ class 1

    def _o2t_packet(self, link: _Link) -> bytes:
        """The O→T datagram, its sequence numbers left for the pump to write: the command image
        with the run/idle header, or an input-only connection's heartbeat."""
        s = self.settings
        if not s.input_only:
            return io.encode_io(
                link.o2t_id, 0, 0, self._command_bytes, io.RUN_BIT if self.run else 0
            )
        if s.heartbeat_o2t_size == 0:
            return io.encode_heartbeat(link.o2t_id, 0)
        if s.heartbeat_o2t_size == 6:
            return io.encode_io(link.o2t_id, 0, 0, b"", 0)
        return io.encode_io(link.o2t_id, 0, 0, b"")

    def _t2o_batch_read(self) -> None:
        """After each wake-up for T→O (a batch, or the pump's word that T→O fell silent for the
        connection timeout): push the fallback timer back and look at the watchdog."""
        link = self._link
        if link is not None and link.o2t is not None:
            link.o2t.t2o_read()
            self._check_t2o_silence(link, asyncio.get_running_loop().time(), 0.0)

    def _check_t2o_silence(self, link: _Link, now: float, lag_s: float) -> None:
        """The watchdog (ethernetip.md "Forward Open": RPI × (4 << multiplier)). Checked after
        each T→O wake-up, including the one the pump gives once T→O has been silent for the
        timeout, and at the O→T stream's fallback timer: a steady T→O stream costs no wake-up of
        its own for it.

        A timer firing more than an RPI late means this loop itself stalled (a busy machine):
        T→O packets may be waiting in the socket, unread. The verdict waits for a timer on time,
        which comes after the loop has read its sockets again."""
        timeout_s = self._timeout_s(link)
        if now - link.last_rx < timeout_s or lag_s > link.o2t_api_us / 1e6:
            return
        if self._lost is not None and not self._lost.done():
            self._lost.set_result(
                f"no T→O for {timeout_s * 1e3:.0f} ms (RPI {link.t2o_api_us / 1e3:g} ms × "
                f"{4 << self.settings.timeout_multiplier}): connection timed out"
            )

    def _t2o_received(self, data: bytes, addr: tuple[str, int], arrived: float) -> None:
        """One T→O datagram (``arrived``: the loop time the kernel received it)."""
        link = self._link
        try:
            packet = io.decode_io(data)
        except EnipError:
            self.malformed += 1
            return
        if link is None or packet.connection_id != link.t2o_id:
            self.foreign += 1
            return
        payload = packet.payload
        if packet.cip_seq is None or len(payload) < self.settings.t2o_size:
            self.malformed += 1
            return
        last_encap = link.last_t2o_encap_seq
        if last_encap is not None and io.seq32_newer(packet.encap_seq, last_encap) <= 0:
            self.stale += 1
            return
        link.last_t2o_encap_seq = packet.encap_seq
        now = arrived
        link.last_rx = now
        self.packets_in += 1
        last_cip = link.last_t2o_cip_seq
        if last_cip is not None:
            ahead = io.seq16_newer(packet.cip_seq, last_cip)
            if ahead == 0:
                self.duplicates += 1
                return
            if ahead < 0:
                self.stale += 1
                return
            if ahead > 1:
                self.gaps += ahead - 1
        link.last_t2o_cip_seq = packet.cip_seq
        decoded = link.last_payload
        if decoded is not None and payload == decoded[0]:
            # The same bytes as the last frame (a robot refreshes its monitoring values about
            # every 100 ms, whatever the RPI): the same immutable Frame, decoded once.
            frame = decoded[1]
        else:
            try:
                frame = decode_frame(payload)
            except CodecError:
                self.malformed += 1
                return
            link.last_payload = (payload, frame)
        # Epoch seconds the kernel received it (read in batches, so not "now").
        received_at = now + (time.time() - time.monotonic())
        previous = link.last_frame_at
        link.last_frame_at = now
        if previous is not None:
            interval_s = now - previous
            self._window.add(interval_s * 1e3)
            if interval_s > link.t2o_api_us * 1.5e-6:
                self.late += 1
        self.frames += 1
        self.latest = (frame, received_at)
        if not self._seeded:
            self._seed(frame)
        if self.on_frame is not None:
            try:
                self.on_frame(frame, received_at, self.frames)
            except Exception:
                log.exception("on_frame callback failed")

    def _seed(self, frame: Frame) -> None:
        """Bumpless takeover: the command image becomes what the robot does now."""
        bits = self._explicit_bits or self.command.bit_input_registers
        self.command = CommandImage(
            controlbox_do=frame.controlbox_do,
            tool_do=frame.tool_do,
            analog_output_type=frame.analog_output_type,
            analog_output=frame.analog_output,
            bit_input_registers=bits,
        )
        self._command_bytes = encode_command(self.command)
        self._seeded = True
        self._rebuild_o2t()
        if self._first_frame is not None and not self._first_frame.done():
            self._first_frame.set_result(None)


__all__ = [
    "ConnectionState",
    "ConnectionStats",
    "NotConnectedError",
    "Originator",
    "OriginatorSettings",
    "ReadOnlyError",
]

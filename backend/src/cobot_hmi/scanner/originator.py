"""Layer: scanner (asyncio I/O, the originator role). Imports the codec, ``cobot_hmi.enip``,
``cobot_hmi.connection_params``, the scanner's own modules and the runtime support
(``udp_endpoint``); never the emulator or the service.

The backend's class 1 connection to the robot, held as a PLC holds it (issue 3, "The
originator"): RegisterSession, Forward Open (exclusive owner, or input-only as a read-only
mode), T→O received on UDP 2222 of the local address, O→T sent from the same socket at the RPI
on a drift-free schedule with the run/idle header (``o2t_stream``: built ahead, sent by the cyclic
pump), a watchdog on T→O silence, reconnection with backoff, and Forward Close +
UnRegisterSession on shutdown.

Any adapter (issue 11, "Scanning any adapter"): the instances and sizes are data; the robot's
layout is only their default. T→O is decoded to the robot's ``Frame`` only when it has the
layout's size or more (and raw mode is not asked for); otherwise each packet's data goes to
``on_data`` as bytes. O→T carries the command image when its size is the layout's, else bytes
(:meth:`Originator.set_o2t_data`), zero-filled to the size.

One socket for many connections: the UDP port is an :class:`~cobot_hmi.scanner.io_port.IoPort`,
shared by every originator of the process on the same local address, or (without one) the
originator's own. T→O is accepted on the connection ID we chose from the moment the Forward
Open leaves, and only from the target's address.

Bumpless takeover: every connection starts **idle**, and its command image is seeded from the
robot's actual outputs in the first T→O frame (and the bit input registers from an explicit
read of the O→T assembly where the target allows it: that read, done before the Forward Open,
is also what the first O→T packet carries), so switching to run changes nothing until someone
writes. O→T data given in the settings (``o2t_data``, ``scan --o2t-hex``) is never taken over:
every packet carries it until it is changed. The state is CONNECTED only once that first frame
has arrived.

A target sending T→O less often than the API it granted is reported once, and once again
when it keeps its grant (``scanner.t2o_pace``): ``on_slow_target`` and ``stats().slow_target``.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import random
import socket
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any

from cobot_hmi import connection_params as cp
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
from cobot_hmi.enip.encapsulation import ENIP_UDP_PORT
from cobot_hmi.enip.errors import EnipError
from cobot_hmi.enip.sequence import DUPLICATE, STALE, SequenceTracker
from cobot_hmi.scanner.io_port import IoPort
from cobot_hmi.scanner.o2t_stream import O2TStream
from cobot_hmi.scanner.session import EnipSession, SessionError
from cobot_hmi.scanner.stats import IntervalWindow
from cobot_hmi.scanner.t2o_pace import PaceWatch, SlowTarget
from cobot_hmi.udp_endpoint import BATCH_PERIOD_S, QueueFullError

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
    """The connection settings' defaults come from their one declaration
    (``cobot_hmi.connection_params``), shared with the service and the emulator."""

    robot_host: str
    tcp_port: int = cp.ENIP_TCP_PORT.default
    local_host: str | None = None
    """The local address of the UDP port and the TCP session. None: the address that routes
    to the target (so another process may hold UDP 2222 on another address); "0.0.0.0": all."""
    local_udp_port: int = cp.CLASS1_UDP_PORT.default
    rpi_us: int = cp.RPI_US.default
    timeout_multiplier: int = cp.TIMEOUT_MULTIPLIER.default
    """Connection timeout = RPI × (4 << multiplier): 2 → RPI × 16."""
    input_only: bool = False
    large_forward_open: bool = False
    config_instance: int = cp.CONFIG_INSTANCE.default
    o2t_instance: int = cp.O2T_INSTANCE.default
    t2o_instance: int = cp.T2O_INSTANCE.default
    heartbeat_instance: int = cp.HEARTBEAT_INSTANCE.default
    o2t_size: int = cp.O2T_SIZE.default
    t2o_size: int = cp.T2O_SIZE.default
    request_t2o_port: int | None = None
    """Ask for T→O on this local port (a Sockaddr Info 0x8001 item) instead of 2222."""
    heartbeat_o2t_size: int = 0
    """O→T connection size of an input-only connection (targets accept 0, 2 or 6)."""
    o2t_data: bytes | None = None
    """The O→T data to send, zero-filled to ``o2t_size``, in every packet until it is changed
    (never replaced by the bumpless takeover). None: what an explicit read of the O→T assembly
    returns (where the target allows it), else zeros, and at the robot layout's sizes the
    takeover of the robot's outputs from the first frame."""
    raw: bool = False
    """Hand every T→O packet's data to ``on_data`` even when its size is the robot layout's."""
    api_bounds_us: tuple[int, int] | None = None
    """The packet intervals (API) a Forward Open reply may grant, inclusive. None: RPI / 2 to
    RPI × 2. A reply outside is refused (and the connection closed): a target granting 1 µs
    would have us send a datagram per microsecond, one granting hours would leave a dead
    connection looking alive."""
    backoff_initial_s: float = 0.1
    backoff_max_s: float = 1.0
    """Longest wait between two attempts at an absent or lost robot: 0.1 s doubling to this.
    About a PLC's own retry period, so a robot back from a restart or a cable pull carries
    frames again within about a second of accepting connections; one TCP connect a second is
    nothing to an absent host (on a network, each attempt to a host that does not answer also
    waits ``tcp_timeout_s`` first)."""
    refused_backoff_max_s: float = 5.0
    """The same for a robot that answers and refuses (a Forward Open error: a wrong
    assembly, a connection another scanner owns): nothing changes for that within a second,
    and every attempt costs the robot a line in its log."""
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

    @property
    def decodes_frames(self) -> bool:
        """T→O is the robot's frame: its layout's size, or longer (a controller configured to
        append general-purpose registers: the frame keeps them as ``extra``), and raw mode not
        asked for."""
        return not self.raw and self.t2o_size >= T2O_SIZE

    @property
    def o2t_is_command(self) -> bool:
        """O→T is the robot's command image (its layout's size, an exclusive owner)."""
        return not self.input_only and self.o2t_size == O2T_SIZE

    @property
    def api_range_us(self) -> tuple[int, int]:
        if self.api_bounds_us is not None:
            return self.api_bounds_us
        return self.rpi_us // 2, self.rpi_us * 2

    def initial_o2t_data(self) -> bytes:
        """``o2t_data`` zero-filled to the O→T size (a ``ValueError`` if it is longer)."""
        return fit_o2t_data(self.o2t_data or b"", self.o2t_size)


def fit_o2t_data(data: bytes, size: int) -> bytes:
    """``data`` zero-filled to ``size`` bytes; a ``ValueError`` when it is longer."""
    if len(data) > size:
        raise ValueError(f"{len(data)} bytes of O→T data exceed the O→T size of {size} bytes")
    return data.ljust(size, b"\x00")


def local_address_to(host_ip: str) -> str:
    """The local address the kernel's routing table picks to reach ``host_ip`` (a UDP
    ``connect`` sends nothing)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        try:
            probe.connect((host_ip, ENIP_UDP_PORT))
        except OSError as error:
            raise OSError(f"no local address routes to {host_ip}: {error}") from None
        address: str = probe.getsockname()[0]
        return address


@dataclass(frozen=True)
class ConnectionStats:
    state: ConnectionState
    reason: str | None
    packets_in: int
    packets_out: int
    gaps: int
    """T→O packets lost on the way: the CIP sequence count's jumps past one, summed (a
    target sending slower than its grant makes none)."""
    duplicates: int
    """T→O packets repeating the last CIP sequence count (no new data)."""
    late: int
    """T→O frames (new data) received more than 1.5 × the granted T→O API after the frame
    before: after a gap or duplicates, or from a target slower than its grant (``slow_target``
    says when it is that)."""
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
    """Datagrams dropped for not being this connection's: its connection ID from another
    address than the target's (forged), or an unknown connection ID from the target's address
    (or from anywhere, on a port of the originator's own)."""
    frames: int = 0
    interval_p50_ms: float | None = None
    rpi_us: int | None = None
    """The T→O actual packet interval of the connection (the target's reply)."""
    slow_target: SlowTarget | None = None
    """The target sends T→O less often than it granted (``scanner.t2o_pace``), while it does."""


class _RefusedError(Exception):
    def __init__(self, reason: str, *, opened: bool = False) -> None:
        super().__init__(reason)
        self.reason = reason
        self.opened = opened
        """The target did open the connection (we refuse its reply): close it."""


@dataclass
class _Link:
    """One Forward Open's worth of negotiated parameters and sequence state."""

    t2o_id: int
    connection_serial: int
    originator_serial: int
    path: bytes
    target_host: str
    """The target's address: T→O from anywhere else is foreign."""
    o2t_api_us: int
    t2o_api_us: int
    """Until the reply is read: the RPI asked for."""
    o2t_id: int = 0
    o2t_addr: tuple[str, int] = ("0.0.0.0", ENIP_UDP_PORT)
    sequence: SequenceTracker = field(default_factory=SequenceTracker)
    last_frame_at: float | None = None
    """Loop time of the last new frame."""
    last_rx: float = 0.0
    """Loop time the kernel received the last accepted T→O packet."""
    last_payload: tuple[bytes, Frame] | None = None
    """The last T→O payload decoded, and its frame."""
    o2t: O2TStream | None = None
    routed: bool = False


class Originator:
    """One class 1 connection to one target. Several may share an :class:`IoPort` (one UDP
    socket of their local address) when they run on the port's event loop."""

    def __init__(
        self,
        settings: OriginatorSettings,
        *,
        on_frame: Callable[[Frame, bytes, float, int], None] | None = None,
        on_state: Callable[[ConnectionState, str | None], None] | None = None,
        on_data: Callable[[bytes, float, int], None] | None = None,
        on_slow_target: Callable[[SlowTarget | None], None] | None = None,
        io_port: IoPort | None = None,
    ) -> None:
        """``on_frame(frame, payload, received_at, t2o_sequence)``: each new T→O frame when T→O
        is the robot's layout, with the payload it was decoded from (consumers that keep bytes
        slice those instead of encoding the frame again); ``on_data(payload, received_at, t2o_sequence)``: each new T→O packet's
        data otherwise (``settings.decodes_frames``). ``received_at``: epoch seconds the kernel
        received it; ``t2o_sequence``: the encapsulation sequence number its packet carried in
        the Sequenced Address item (CIP Vol 2 §2-6, §3-4.2; UDINT, the target raises it per
        packet), so a consumer can tell the frames it keeps apart by the wire's own numbering
        (``frames`` counts them). ``on_slow_target(slow)``: the target was found sending T→O
        slower than its grant (a ``SlowTarget``), or keeping it again (None), once each time
        (``scanner.t2o_pace``). ``io_port``: the UDP port to share (None: one of
        our own, opened on start and closed on stop). A ``ValueError`` when ``o2t_data`` does
        not fit the O→T size."""
        self.settings = settings
        self.on_frame = on_frame
        self.on_state = on_state
        self.on_data = on_data
        self.on_slow_target = on_slow_target
        self.state = ConnectionState.IDLE
        self.reason: str | None = None
        self.latest: tuple[Frame, float] | None = None
        """The last frame and its epoch receive time (T→O of the robot's layout)."""
        self.latest_data: tuple[bytes, float] | None = None
        """The last T→O data and its epoch receive time (T→O of any other size, or raw)."""
        self.run = False
        self.command: CommandImage = zero_command()
        self._o2t_bytes = settings.initial_o2t_data()
        if settings.o2t_is_command:
            if settings.o2t_data is not None:
                self.command = decode_command(self._o2t_bytes)
            self._o2t_bytes = encode_command(self.command)
        self._rng = random.Random()
        self._port = io_port
        self._owns_port = io_port is None
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
        self._pace = PaceWatch()
        self._connected_since: float | None = None
        self.packets_in = 0
        self._packets_out_closed = 0
        """O→T packets sent by the streams of connections closed since."""
        self.gaps = 0
        self.duplicates = 0
        self.late = 0
        self.malformed = 0
        self.stale = 0
        self.foreign = 0
        self.frames = 0

    # ------------------------------------------------------------------ public interface

    @property
    def io_port(self) -> IoPort | None:
        """The UDP port the connection uses (None before a start without a shared port)."""
        return self._port

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
        self._set_state(ConnectionState.IDLE, None)

    def stats(self) -> ConnectionStats:
        figures = self._window.figures()
        latest = self.latest or self.latest_data
        link = self._link
        port = self._port
        # On a port of our own, every stray datagram is ours to count.
        own = port if self._owns_port and port is not None else None
        return ConnectionStats(
            state=self.state,
            reason=self.reason,
            packets_in=self.packets_in,
            packets_out=self.packets_out,
            gaps=self.gaps,
            duplicates=self.duplicates,
            late=self.late,
            malformed=self.malformed + (own.malformed if own is not None else 0),
            interval_mean_ms=figures.mean_ms,
            interval_p99_ms=figures.p99_ms,
            interval_max_ms=figures.max_ms,
            last_frame_age_s=time.time() - latest[1] if latest is not None else None,
            connected_since=self._connected_since,
            stale=self.stale,
            foreign=self.foreign + (own.foreign if own is not None else 0),
            frames=self.frames,
            interval_p50_ms=figures.p50_ms,
            rpi_us=link.t2o_api_us if link is not None and link.o2t is not None else None,
            slow_target=self._pace.slow if link is not None else None,
        )

    @property
    def packets_out(self) -> int:
        """O→T packets that left (counted by the cyclic pump as it sends them)."""
        link = self._link
        current = link.o2t.sent if link is not None and link.o2t is not None else 0
        return self._packets_out_closed + current

    def pump_counters(self) -> dict[str, int]:
        """The cyclic pump's counters (``UdpEndpoint.counters``; the whole port's when it is
        shared), empty without an open port."""
        port = self._port
        return port.udp.counters() if port is not None and port.is_open else {}

    def set_run(self, run: bool) -> None:
        if self.settings.input_only:
            raise ReadOnlyError("input-only connection: the outputs belong to another owner")
        if self.state is not ConnectionState.CONNECTED:
            raise NotConnectedError(f"not connected ({self.state}: {self.reason or 'no reason'})")
        if run != self.run:
            self.run = run
            self._rebuild_o2t()

    @property
    def o2t_data(self) -> bytes:
        """The O→T data the next packet carries (after the run/idle header)."""
        return self._o2t_bytes

    def set_o2t_data(self, data: bytes) -> int:
        """Put ``data`` (zero-filled to the O→T size) on the wire as it is; returns the
        ``packets_out`` count after which it has gone out. A ``ValueError`` when it is longer
        than the O→T size or the connection has no O→T data (input-only)."""
        s = self.settings
        if s.input_only:
            raise ReadOnlyError("input-only connection: it sends no O→T data")
        fitted = fit_o2t_data(data, s.o2t_size)
        if s.o2t_is_command:
            self.command = decode_command(fitted)
        self._o2t_bytes = fitted
        self._rebuild_o2t()
        return self.packets_out + 1

    def set_command(self, image: CommandImage) -> int:
        """Put ``image`` on the wire; returns the ``packets_out`` count after which it has
        gone out (see :meth:`wait_sent`). A ``ValueError`` when O→T is not the robot's command
        image (another size: :meth:`set_o2t_data`)."""
        if not self.settings.o2t_is_command:
            raise ValueError(
                f"O→T of {self.settings.o2t_size} bytes is not the robot's command image"
            )
        self.command = image
        self._o2t_bytes = encode_command(image)
        # The pump's stream carries the new image from its next packet on.
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
                port = await self._open_port()
                await self._connect_once(port)
            except _RefusedError as refused:
                self._set_state(ConnectionState.REFUSED, refused.reason)
                await self._teardown(forward_close=refused.opened)
            except (OSError, SessionError, EnipError, TimeoutError, QueueFullError) as error:
                self._set_state(ConnectionState.LOST, str(error) or type(error).__name__)
                await self._teardown(forward_close=True)
            else:
                backoff_s = s.backoff_initial_s
                assert self._lost is not None
                reason = await self._lost
                self._set_state(ConnectionState.LOST, reason)
                await self._teardown(forward_close=True)
            await asyncio.sleep(backoff_s)
            cap_s = (
                s.refused_backoff_max_s
                if self.state is ConnectionState.REFUSED
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
        await self._read_o2t_assembly(session)

        o2t_point = s.heartbeat_instance if s.input_only else s.o2t_instance
        o2t_size = s.heartbeat_o2t_size if s.input_only else s.o2t_size + 6
        link = _Link(
            t2o_id=port.new_connection_id(),
            connection_serial=self._rng.getrandbits(16),
            originator_serial=self._rng.getrandbits(32),
            path=epath.connection_path(s.config_instance, o2t_point, s.t2o_instance),
            target_host=session.peer_host or await self._target_ip(),
            o2t_api_us=s.rpi_us,
            t2o_api_us=s.rpi_us,
            last_rx=loop.time(),
        )
        request = ForwardOpenRequest(
            o2t_connection_id=0,
            t2o_connection_id=link.t2o_id,
            connection_serial=link.connection_serial,
            vendor_id=ORIGINATOR_VENDOR_ID,
            originator_serial=link.originator_serial,
            timeout_multiplier=s.timeout_multiplier,
            o2t_rpi_us=s.rpi_us,
            o2t_params=NetworkParams(o2t_size, ConnectionType.POINT_TO_POINT, Priority.SCHEDULED),
            t2o_rpi_us=s.rpi_us,
            t2o_params=NetworkParams(
                s.t2o_size + 2, ConnectionType.POINT_TO_POINT, Priority.SCHEDULED
            ),
            path=link.path,
            large=s.large_forward_open,
        )
        extra: list[CpfItem] = []
        if s.request_t2o_port is not None:
            extra.append(sockaddr_item(ItemType.SOCKADDR_T2O, Sockaddr("0.0.0.0", port.udp_port)))
        self.run = False
        self._seeded = False
        self._window.clear()
        self._pace.restart(s.rpi_us)  # again with the API the reply grants
        self._lost = loop.create_future()
        self._first_frame = loop.create_future()
        self._link = link
        # A point-to-point T→O connection ID is ours (CIP Vol 1 §3-5.4.1): the target may
        # produce on it as soon as it has opened the connection, before we read its reply.
        self._route(port, link, silence_s=0.0)
        response, items = await session.request(request.request(), extra)
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
        self._pace.restart(link.t2o_api_us)
        link.o2t_addr = (link.target_host, ENIP_UDP_PORT)
        for item in items:
            if item.type_id == ItemType.SOCKADDR_O2T:
                announced = decode_sockaddr(item.data)
                host = announced.host if announced.host != "0.0.0.0" else link.target_host
                link.o2t_addr = (host, announced.port)
        # O→T from now on, at the RPI, built ahead into the cyclic pump (o2t_stream).
        link.o2t = O2TStream(
            port.udp,
            port.new_tag(),
            link.o2t_addr,
            link.o2t_api_us / 1e6,
            lambda: self._o2t_packet(link),
            has_cip_seq=not (s.input_only and s.heartbeat_o2t_size == 0),
            wake_period_s=self._t2o_batch_s,
            on_timer=lambda now, lag_s: self._check_t2o_silence(link, now, lag_s),
        )
        link.o2t.start()
        # The pump wakes us once T→O has been silent for the timeout, whatever the batch.
        self._route(port, link, silence_s=self._timeout_s(link))
        first_timeout_s = max(s.first_frame_timeout_s, self._timeout_s(link))
        waits: list[asyncio.Future[Any]] = [self._first_frame, self._lost]
        done, _ = await asyncio.wait(
            waits, timeout=first_timeout_s, return_when=asyncio.FIRST_COMPLETED
        )
        if self._first_frame not in done:
            raise TimeoutError(
                f"no T→O frame within {first_timeout_s:.1f} s of the Forward Open "
                f"(T→O connection 0x{link.t2o_id:08X} on UDP {port.local_host}:{port.udp_port})"
            )
        self._connected_since = time.time()
        self._set_state(ConnectionState.CONNECTED, None)

    def _route(self, port: IoPort, link: _Link, *, silence_s: float) -> None:
        port.route(
            link.t2o_id,
            link.target_host,
            self,
            batch_s=self._t2o_batch_s,
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

    async def _read_o2t_assembly(self, session: EnipSession) -> None:
        """Read the O→T assembly's data explicitly where the target allows it (most refuse
        while another connection owns it): the first O→T packet carries it, and the command
        image's bit input registers keep it (bumpless takeover). Nothing changes when the read
        fails, or when ``o2t_data`` was given."""
        s = self.settings
        self._explicit_bits = None
        if s.input_only or s.o2t_data is not None:
            return
        try:
            response = await session.get_attribute_single(epath.CLASS_ASSEMBLY, s.o2t_instance, 3)
        except EnipError:
            return
        if not response.ok or len(response.data) != s.o2t_size:
            return
        if s.o2t_is_command:
            try:
                image = decode_command(response.data)
            except CodecError:
                return
            self.command = image
            self._explicit_bits = image.bit_input_registers
        self._o2t_bytes = bytes(response.data)

    @property
    def _t2o_batch_s(self) -> float:
        s = self.settings
        return s.t2o_batch_s if s.rpi_us < BATCH_PERIOD_S * 1e6 else 0.0

    def _timeout_s(self, link: _Link) -> float:
        return connection_timeout_us(link.t2o_api_us, self.settings.timeout_multiplier) / 1e6

    async def _teardown(self, *, forward_close: bool) -> None:
        link, self._link = self._link, None
        port = self._port
        if link is not None:
            if link.o2t is not None:
                self._packets_out_closed += link.o2t.stop()
            if link.routed and port is not None:
                port.unroute(link.t2o_id)
                link.routed = False
        for future in (self._lost, self._first_frame):
            if future is not None and not future.done():
                future.cancel()
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
        if self.state is ConnectionState.CONNECTED and not self._stopping:
            self._set_state(ConnectionState.LOST, "connection closed")
        self.run = False
        self._connected_since = None

    async def _forward_close(self, session: EnipSession | None, link: _Link) -> None:
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

    # ------------------------------------------------------------------ class 1

    def _o2t_packet(self, link: _Link) -> bytes:
        """The O→T datagram, its sequence numbers left for the pump to write: the O→T data
        with the run/idle header, or an input-only connection's heartbeat."""
        s = self.settings
        if not s.input_only:
            return io.encode_io(link.o2t_id, 0, 0, self._o2t_bytes, io.RUN_BIT if self.run else 0)
        if s.heartbeat_o2t_size == 0:
            return io.encode_heartbeat(link.o2t_id, 0)
        if s.heartbeat_o2t_size == 6:
            return io.encode_io(link.o2t_id, 0, 0, b"", 0)
        return io.encode_io(link.o2t_id, 0, 0, b"")

    # T2OConsumer: what the IoPort hands us.

    def t2o_batch_read(self) -> None:
        """After each wake-up for T→O (a batch, or the pump's word that T→O fell silent for the
        connection timeout): push the fallback timer back and look at the watchdog."""
        link = self._link
        if link is not None and link.o2t is not None:
            link.o2t.t2o_read()
            self._check_t2o_silence(link, asyncio.get_running_loop().time(), 0.0)

    def t2o_foreign(self) -> None:
        self.foreign += 1

    def t2o_malformed(self) -> None:
        self.malformed += 1

    def _check_t2o_silence(self, link: _Link, now: float, lag_s: float) -> None:
        """The watchdog (docs/protocol.md, Forward Open: RPI × (4 << multiplier)). Checked after
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

    def t2o_packet(self, packet: io.IoPacket, arrived: float) -> None:
        """One T→O packet of this connection from the target's address (``arrived``: the loop
        time the kernel received it)."""
        link = self._link
        if link is None:
            self.foreign += 1
            return
        payload = packet.payload
        s = self.settings
        if packet.cip_seq is None or len(payload) != s.t2o_size:
            self.malformed += 1
            return
        verdict = link.sequence.accept(packet.encap_seq, packet.cip_seq)
        if verdict is STALE:
            self.stale += 1
            return
        link.last_rx = arrived
        self.packets_in += 1
        if self._pace.packet(arrived, packet.encap_seq):
            self._report_pace()
        if verdict is DUPLICATE:
            self.duplicates += 1
            return
        self.gaps += link.sequence.missed
        # Epoch seconds the kernel received it (read in batches, so not "now").
        received_at = arrived + (time.time() - time.monotonic())
        if not s.decodes_frames:
            self._count_frame(link, arrived)
            self.latest_data = (payload, received_at)
            self._first_data()
            if self.on_data is not None:
                try:
                    self.on_data(payload, received_at, packet.encap_seq)
                except Exception:
                    log.exception("on_data callback failed")
            return
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
        self._count_frame(link, arrived)
        self.latest = (frame, received_at)
        if not self._seeded:
            self._seed(frame)
        if self.on_frame is not None:
            try:
                self.on_frame(frame, payload, received_at, packet.encap_seq)
            except Exception:
                log.exception("on_frame callback failed")

    def _count_frame(self, link: _Link, arrived: float) -> None:
        previous = link.last_frame_at
        link.last_frame_at = arrived
        if previous is not None:
            interval_s = arrived - previous
            self._window.add(interval_s * 1e3)
            if interval_s > link.t2o_api_us * 1.5e-6:
                self.late += 1
        self.frames += 1

    def _report_pace(self) -> None:
        slow, found = self._pace.slow, self._pace.found
        if slow is not None:
            log.info("T→O of %s: %s", self.settings.robot_host, slow.words())
        elif found is not None:
            log.info("T→O of %s: %s", self.settings.robot_host, found.kept_words())
        if self.on_slow_target is not None:
            try:
                self.on_slow_target(slow)
            except Exception:
                log.exception("on_slow_target callback failed")

    def _first_data(self) -> None:
        if self._first_frame is not None and not self._first_frame.done():
            self._first_frame.set_result(None)

    def _seed(self, frame: Frame) -> None:
        """Bumpless takeover: the command image becomes what the robot does now, unless the
        O→T data was given (``o2t_data``: what is sent is what was asked for)."""
        self._seeded = True
        if self.settings.o2t_is_command and self.settings.o2t_data is None:
            bits = self._explicit_bits or self.command.bit_input_registers
            self.command = CommandImage(
                controlbox_do=frame.controlbox_do,
                tool_do=frame.tool_do,
                analog_output_type=frame.analog_output_type,
                analog_output=frame.analog_output,
                bit_input_registers=bits,
            )
            self._o2t_bytes = encode_command(self.command)
            self._rebuild_o2t()
        self._first_data()


def _source_host(port: IoPort) -> str | None:
    """The TCP session's source address: the target sends T→O to the address our TCP
    connection comes from (docs/operations.md, ports and addresses): the port's address."""
    host = port.local_host
    return None if host in ("0.0.0.0", "") else host


__all__ = [
    "ConnectionState",
    "ConnectionStats",
    "NotConnectedError",
    "Originator",
    "OriginatorSettings",
    "ReadOnlyError",
    "fit_o2t_data",
    "local_address_to",
]

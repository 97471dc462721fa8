"""Layer: runtime support for the I/O layers (emulator, scanner). Imports only ``native``.

The UDP socket of a class 1 endpoint (UDP 2222 on either side) and its cyclic pump
(``native``: the C thread of ``native/cyclic_pump.c``, or its pure-Python twin when the
extension cannot be loaded or ``COBOT_HMI_PUMP=python``; ``implementation`` says which): a
thread that sends the datagrams queued with :meth:`send_at` at
their due times, sends periodic streams (:meth:`send_every`: a template whose two counters it
raises per packet), and reads the socket into a ring with the kernel's receive time of each
datagram (``SO_TIMESTAMPNS``). Python hands over whole datagrams, built by ``cobot_hmi.enip``;
the pump only keeps time.

Why: each wake-up of a Python thread costs far more CPU than the packet it serves (a context
switch into a cold interpreter: 60-100 µs on a shared VM, against a few µs to build or decode a
packet), and a class 1 endpoint at RPI 2 ms has a packet to send every 2 ms. With the pump, the
owner wakes once per *batch*: it queues the next few RPIs' packets ahead and reads what arrived
meanwhile, with the time each arrived, so nothing is measured late for being read late.

Reading (``watch``):

- ``watch(True)``: the pump reads each datagram as it arrives and wakes the owner's event loop
  for it (``batch_s`` 0), or at most every ``batch_s`` while datagrams keep coming;
- ``watch(False)``: the pump reads the socket at its own send wake-ups only and never wakes the
  owner, who reads by calling :meth:`drain` from its own timer (a target producing at a short
  RPI, as a controller reads its inputs once per cycle).

Closing: :meth:`close` (or leaving a ``with`` block) stops and joins the pump's thread and closes
the socket; an endpoint dropped without either is closed by its finalizer (the event loop's
reader holds only a weak reference to it), so no thread outlives its endpoint.

Why not asyncio's datagram transport: it receives every datagram into a 256 KiB buffer and then
shrinks it (two system calls and a page fault per packet, measured with ``perf stat``).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import socket
import struct
import weakref
from collections.abc import Callable
from types import TracebackType
from typing import Final

from cobot_hmi.native import Implementation, PumpLike, pump_class, pure

log = logging.getLogger(__name__)

_SO_TIMESTAMPNS: Final = getattr(socket, "SO_TIMESTAMPNS", 35)
"""Linux's ``SO_TIMESTAMPNS`` (asm-generic socket.h; Python's ``socket`` module lacks the name)."""
TAKE_BATCH: Final = 64
"""Datagrams moved out of the pump's ring per call."""
RING_SLOTS: Final = 256
"""Received datagrams the pump holds between two reads of its owner (a full ring drops the
oldest: 0.5 s of packets at RPI 2 ms)."""
QUEUE_SLOTS: Final = 256
"""Datagrams queued ahead at most."""
PERIODIC_MAX: Final = pure.PERIODIC_MAX
"""Periodic streams (one per class 1 connection) one endpoint sends at once; the C pump holds
as many (``PUMP_PERIODIC_MAX``, native/cyclic_pump.h)."""
BATCH_PERIOD_S: Final = 0.010
"""Below this RPI an owner wakes once per batch rather than once per packet (its own batch
period: ``TargetSettings.batch_period_s``, ``OriginatorSettings.t2o_batch_s``); at it and above,
once per packet, so the service's default RPI (10 ms) keeps a command one packet away (an
originator's port shared by many connections wakes every ``io_port.BUSY_BATCH_S`` instead).
Also the O→T stream's default wake period."""

PacketHandler = Callable[[bytes, tuple[str, int], float], None]
"""``(data, source address, loop time the kernel received it)``."""


class QueueFullError(RuntimeError):
    """More datagrams queued ahead than the pump holds."""


class UdpEndpoint:
    def __init__(
        self,
        host: str,
        port: int,
        on_packet: PacketHandler,
        *,
        receive_size: int,
        kernel_timestamps: bool = True,
        on_batch: Callable[[], None] | None = None,
        ring_slots: int = RING_SLOTS,
        receive_buffer_bytes: int | None = None,
    ) -> None:
        """``receive_size``: one more than the longest datagram the owner accepts (a longer one
        then arrives as exactly this long, still too long). Every datagram carries the kernel's
        receive time; ``kernel_timestamps`` False uses the pump's read time instead.
        ``on_batch``: called after each wake-up ``watch`` asked for (a batch, or a silence),
        once what came has been handed on. ``ring_slots``: datagrams the pump holds for its
        owner (an endpoint shared by many connections wants more). ``receive_buffer_bytes``:
        the socket's kernel receive buffer asked for (the kernel caps it at
        ``net.core.rmem_max``); ``None`` keeps the system's default."""
        self._loop = asyncio.get_running_loop()
        self._on_packet = on_packet
        self._on_batch = on_batch
        self._receive_size = receive_size
        pump_type, implementation = pump_class()
        self.implementation: Implementation = implementation
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            sock.setblocking(False)
            if kernel_timestamps:
                sock.setsockopt(socket.SOL_SOCKET, _SO_TIMESTAMPNS, 1)
            if receive_buffer_bytes is not None:
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, receive_buffer_bytes)
            sock.bind((host, port))
            pump = pump_type(sock.fileno(), QUEUE_SLOTS, receive_size, ring_slots, receive_size)
        except (OSError, ValueError):
            sock.close()
            raise
        self._sock: socket.socket | None = sock
        self._pump: PumpLike | None = pump
        self._notify_fd: int = pump.notify_fd()
        self.port: int = sock.getsockname()[1]
        self.watching = False
        self._reading = False
        self._sources: dict[int, tuple[str, int]] = {}
        self._addresses: dict[tuple[str, int], tuple[int, int]] = {}
        self._finalizer = weakref.finalize(self, _release, pump, sock, self._loop, self._notify_fd)

    def __enter__(self) -> UdpEndpoint:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.close()

    # ------------------------------------------------------------------ receiving

    def watch(self, on: bool, batch_s: float = 0.0, *, silence_s: float = 0.0) -> None:
        """Wake the owner for arriving datagrams (True: at once, or at most every ``batch_s``),
        or not (False: the owner calls ``drain`` from its own timer); either way, once when no
        datagram has come for ``silence_s`` (0: never), a watchdog's cue. Each such wake-up
        reads what came, then calls ``on_batch``."""
        pump = self._pump
        if pump is None:
            return
        silence_ns = round(silence_s * 1e9)
        if on:
            pump.configure(not batch_s, round(batch_s * 1e9), silence_ns)
        else:
            pump.configure(False, -1, silence_ns)  # -1: no batch notifications
        if not self._reading:
            # A weak reference: the loop must not keep a dropped endpoint (and its thread) alive.
            self._loop.add_reader(self._notify_fd, _notified, weakref.ref(self))
            self._reading = True
        self.watching = on

    def _notified(self) -> None:
        self.drain()
        if self._on_batch is not None:
            self._on_batch()

    def drain(self) -> None:
        """Hand every datagram received so far to ``on_packet``, in arrival order."""
        on_packet, known = self._on_packet, self._sources.get
        while (pump := self._pump) is not None:
            taken = pump.take(True, TAKE_BATCH)
            for data, ip, port, stamp_ns in taken:
                # ``_source``'s lookup inline: per datagram, and the source almost always known.
                source = known(ip << 16 | port) or self._source(ip, port)
                on_packet(data, source, stamp_ns * 1e-9)
            if len(taken) < TAKE_BATCH:
                break

    def _source(self, ip: int, port: int) -> tuple[str, int]:
        key = ip << 16 | port
        source = self._sources.get(key)
        if source is None:
            source = (socket.inet_ntoa(struct.pack("!I", ip)), port)
            if len(self._sources) < 4096:  # a flood of forged sources must not grow it forever
                self._sources[key] = source
        return source

    # ------------------------------------------------------------------ sending

    def sendto(self, data: bytes, addr: tuple[str, int]) -> bool:
        """Send now; whether the packet left (a full buffer or an unreachable peer loses it)."""
        sock = self._sock
        if sock is None:
            return False
        try:
            sock.sendto(data, addr)
        except OSError as error:
            log.debug("UDP send to %s:%d failed: %s", *addr, error)
            return False
        return True

    def send_at(self, due: float, data: bytes, addr: tuple[str, int], tag: int) -> None:
        """Queue ``data`` to leave at loop time ``due`` (``time.monotonic``), under ``tag`` (the
        owner's name for a stream of packets, for ``cancel`` and ``queued``)."""
        pump = self._pump
        if pump is None:
            return
        address = self._address(addr)
        result = pump.queue(round(due * 1e9), address[0], address[1], data, tag)
        if result == -1:
            raise QueueFullError(f"{QUEUE_SLOTS} datagrams already queued")
        if result != 0:
            raise ValueError(f"a {len(data)}-byte datagram does not fit a queue slot")

    def _address(self, addr: tuple[str, int]) -> tuple[int, int]:
        address = self._addresses.get(addr)
        if address is None:
            ip = struct.unpack("!I", socket.inet_aton(addr[0]))[0]
            address = self._addresses[addr] = (ip, addr[1])
        return address

    def send_every(  # noqa: PLR0917
        self,
        tag: int,
        first_due: float,
        period_s: float,
        data: bytes,
        addr: tuple[str, int],
        counter32: tuple[int, int] | None,
        counter16: tuple[int, int] | None = None,
    ) -> None:
        """Send ``data`` every ``period_s`` from loop time ``first_due`` on (a periodic stream
        under ``tag``, replacing one with the same tag), without waking us. ``counter32`` and
        ``counter16``: ``(offset, first value)`` of a little-endian counter the pump writes
        into each packet and raises by one after it."""
        pump = self._pump
        if pump is None:
            return
        ip, port = self._address(addr)
        off32, first32 = counter32 if counter32 is not None else (-1, 0)
        off16, first16 = counter16 if counter16 is not None else (-1, 0)
        result = pump.periodic_start(
            tag,
            round(first_due * 1e9),
            round(period_s * 1e9),
            ip,
            port,
            data,
            off32,
            first32 & 0xFFFFFFFF,
            off16,
            first16 & 0xFFFF,
        )
        if result == -1:
            raise QueueFullError("every periodic stream of the pump is in use")
        if result != 0:
            raise ValueError(f"a {len(data)}-byte periodic datagram does not fit its counters")

    def replace_periodic(self, tag: int, data: bytes) -> bool:
        """The periodic stream ``tag`` sends ``data`` from its next packet on (its counters go
        on); False when there is no such stream."""
        pump = self._pump
        if pump is None:
            return False
        result = pump.periodic_data(tag, data)
        if result == -2:
            raise ValueError(f"a {len(data)}-byte periodic datagram does not fit its counters")
        return bool(result == 0)

    def periodic_next(self, tag: int, *, stop: bool = False) -> tuple[int, int, float] | None:
        """The periodic stream ``tag``'s next packet: its 32-bit and 16-bit counters and its
        due loop time; ``stop`` ends the stream (that packet is not sent). None when there is
        no such stream."""
        pump = self._pump
        if pump is None:
            return None
        state = pump.periodic_next(tag, stop)
        if state is None:
            return None
        next32, next16, due_ns = state
        return next32, next16, due_ns * 1e-9

    def stop_periodic(self, tag: int) -> tuple[int, int, float] | None:
        """Stop the periodic stream ``tag`` (see ``periodic_next``)."""
        return self.periodic_next(tag, stop=True)

    def cancel(self, tag: int, from_due: float = 0.0) -> tuple[int, float | None]:
        """Take back the datagrams of ``tag`` (-1: all) not sent yet and due at or after
        ``from_due``: how many, and the earliest one's due time."""
        pump = self._pump
        if pump is None:
            return 0, None
        count, first_due_ns = pump.cancel(tag, round(from_due * 1e9))
        return count, (first_due_ns * 1e-9 if count else None)

    def queued(self, tag: int) -> int:
        """How many datagrams of ``tag`` wait to be sent."""
        pump = self._pump
        return 0 if pump is None else pump.queued(tag)

    def counters(self) -> dict[str, int]:
        """The pump's: sent, send errors, received, ring overflows, wake-ups, the latest a
        datagram left after its due time (ns), and 1 if its thread got real-time priority."""
        pump = self._pump
        values = (0,) * 7 if pump is None else pump.counters()
        names = (
            "sent",
            "send_errors",
            "received",
            "ring_overflows",
            "wakeups",
            "max_late_ns",
            "realtime",
        )
        return dict(zip(names, values, strict=True))

    def close(self) -> None:
        """Stop the pump's thread (joined), then close the socket. Idempotent."""
        self._reading = False
        self.watching = False
        self._pump = None
        self._sock = None
        self._finalizer()


def _notified(endpoint_ref: weakref.ref[UdpEndpoint]) -> None:
    endpoint = endpoint_ref()
    if endpoint is not None:
        endpoint._notified()


def _release(
    pump: PumpLike, sock: socket.socket, loop: asyncio.AbstractEventLoop, notify_fd: int
) -> None:
    """Close an endpoint's pump and socket: from ``close``, or as the finalizer of one dropped
    unclosed (which must not hold the endpoint)."""
    try:
        running: asyncio.AbstractEventLoop | None = asyncio.get_running_loop()
    except RuntimeError:
        running = None
    if running is loop or not loop.is_running():
        loop.remove_reader(notify_fd)  # nothing when it was not watched or the loop is closed
    else:  # dropped on another thread: the loop's own thread unregisters it
        with contextlib.suppress(RuntimeError):  # closed meanwhile: nothing to unregister
            loop.call_soon_threadsafe(loop.remove_reader, notify_fd)
    pump.close()  # stops and joins the thread first
    sock.close()


__all__ = [
    "BATCH_PERIOD_S",
    "PERIODIC_MAX",
    "PacketHandler",
    "QueueFullError",
    "UdpEndpoint",
]

"""Layer: runtime support for the I/O layers (emulator, scanner). Imports only ``native``.

The UDP socket of a class 1 endpoint (UDP 2222 on either side) and its cyclic pump
(``native/cyclic_pump.c``): a C thread that sends the datagrams queued with :meth:`send_at` at
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

Why not asyncio's datagram transport: it receives every datagram into a 256 KiB buffer and then
shrinks it (two system calls and a page fault per packet, measured with ``perf stat``).
"""

from __future__ import annotations

import asyncio
import ctypes
import logging
import socket
import struct
from collections.abc import Callable
from typing import Final

from cobot_hmi.native import cyclic_pump_library

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
BATCH_PERIOD_S: Final = 0.010
"""Below this RPI an owner wakes once per batch rather than once per packet (its own batch
period: ``TargetSettings.batch_period_s``, ``OriginatorSettings.t2o_batch_s``); at it and above,
once per packet, so the service's default RPI (10 ms) keeps a command one packet away. Also
the O→T stream's default wake period."""

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
    ) -> None:
        """``receive_size``: one more than the longest datagram the owner accepts (a longer one
        then arrives as exactly this long, still too long). Every datagram carries the kernel's
        receive time; ``kernel_timestamps`` False uses the pump's read time instead.
        ``on_batch``: called after each wake-up ``watch`` asked for (a batch, or a silence),
        once what came has been handed on."""
        self._loop = asyncio.get_running_loop()
        self._on_packet = on_packet
        self._on_batch = on_batch
        self._receive_size = receive_size
        lib = cyclic_pump_library()
        self._lib = lib
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            sock.setblocking(False)
            if kernel_timestamps:
                sock.setsockopt(socket.SOL_SOCKET, _SO_TIMESTAMPNS, 1)
            sock.bind((host, port))
        except OSError:
            sock.close()
            raise
        pump = lib.pump_new(sock.fileno(), QUEUE_SLOTS, receive_size, RING_SLOTS, receive_size)
        if not pump or lib.pump_start(pump) != 0:
            if pump:
                lib.pump_free(pump)
            sock.close()
            raise OSError("cannot start the cyclic pump thread")
        self._sock: socket.socket | None = sock
        self._pump: int | None = pump
        self._notify_fd: int = lib.pump_notify_fd(pump)
        self.port: int = sock.getsockname()[1]
        self.watching = False
        self._reading = False
        self._buffer = bytearray(TAKE_BATCH * receive_size)
        self._buffer_c = (ctypes.c_char * len(self._buffer)).from_buffer(self._buffer)
        self._lens = (ctypes.c_int32 * TAKE_BATCH)()
        self._stamps = (ctypes.c_int64 * TAKE_BATCH)()
        self._ips = (ctypes.c_uint32 * TAKE_BATCH)()
        self._ports = (ctypes.c_uint16 * TAKE_BATCH)()
        self._view = memoryview(self._buffer)
        self._sources: dict[int, tuple[str, int]] = {}
        self._addresses: dict[tuple[str, int], tuple[int, int]] = {}
        self._first_due = ctypes.c_int64()

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
            self._lib.pump_configure(pump, 0 if batch_s else 1, round(batch_s * 1e9), silence_ns)
        else:
            self._lib.pump_configure(pump, 0, -1, silence_ns)  # -1: no batch notifications
        if not self._reading:
            self._loop.add_reader(self._notify_fd, self._notified)
            self._reading = True
        self.watching = on

    def _notified(self) -> None:
        self.drain()
        if self._on_batch is not None:
            self._on_batch()

    def drain(self) -> None:
        """Hand every datagram received so far to ``on_packet``, in arrival order."""
        lib, on_packet, view = self._lib, self._on_packet, self._view
        buffer_c, size = self._buffer_c, len(self._buffer)
        lens, stamps, ips, ports = self._lens, self._stamps, self._ips, self._ports
        while (pump := self._pump) is not None:
            count = lib.pump_take(pump, 1, buffer_c, size, lens, stamps, ips, ports, TAKE_BATCH)
            if count:
                # Whole arrays out of ctypes at once (indexing them one by one costs more).
                offset = 0
                for length, stamp, ip, port in zip(
                    lens[:count], stamps[:count], ips[:count], ports[:count], strict=True
                ):
                    data = bytes(view[offset : offset + length])
                    offset += length
                    on_packet(data, self._source(ip, port), stamp * 1e-9)
            if count < TAKE_BATCH:
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
        result = self._lib.pump_queue(
            pump, round(due * 1e9), address[0], address[1], data, len(data), tag
        )
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
        result = self._lib.pump_periodic_start(
            pump,
            tag,
            round(first_due * 1e9),
            round(period_s * 1e9),
            ip,
            port,
            data,
            len(data),
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
        result = self._lib.pump_periodic_data(pump, tag, data, len(data))
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
        next32, next16, due_ns = ctypes.c_uint32(), ctypes.c_uint16(), ctypes.c_int64()
        found = self._lib.pump_periodic_next(
            pump, tag, int(stop), ctypes.byref(next32), ctypes.byref(next16), ctypes.byref(due_ns)
        )
        if found != 0:
            return None
        return next32.value, next16.value, due_ns.value * 1e-9

    def stop_periodic(self, tag: int) -> tuple[int, int, float] | None:
        """Stop the periodic stream ``tag`` (see ``periodic_next``)."""
        return self.periodic_next(tag, stop=True)

    def cancel(self, tag: int, from_due: float = 0.0) -> tuple[int, float | None]:
        """Take back the datagrams of ``tag`` (-1: all) not sent yet and due at or after
        ``from_due``: how many, and the earliest one's due time."""
        pump = self._pump
        if pump is None:
            return 0, None
        first = self._first_due
        count: int = self._lib.pump_cancel(pump, tag, round(from_due * 1e9), ctypes.byref(first))
        return count, (first.value * 1e-9 if count else None)

    def queued(self, tag: int) -> int:
        """How many datagrams of ``tag`` wait to be sent."""
        pump = self._pump
        return 0 if pump is None else int(self._lib.pump_queued(pump, tag))

    def counters(self) -> dict[str, int]:
        """The pump's: sent, send errors, received, ring overflows, wake-ups, the latest a
        datagram left after its due time (ns), and 1 if its thread got real-time priority."""
        values = (ctypes.c_int64 * 7)()
        if self._pump is not None:
            self._lib.pump_counters(self._pump, values)
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
        if self._reading:
            self._loop.remove_reader(self._notify_fd)
            self._reading = False
        self.watching = False
        pump, self._pump = self._pump, None
        if pump is not None:
            self._lib.pump_free(pump)  # stops and joins the thread first
        sock, self._sock = self._sock, None
        if sock is not None:
            sock.close()
        self._view.release()


__all__ = ["BATCH_PERIOD_S", "PacketHandler", "QueueFullError", "UdpEndpoint"]

"""Layer: runtime support. Imports only ``eventloop`` (its precise epoll selector).

The cyclic pump in Python: the same interface and behaviour as the extension
(``_cyclic_pump_module.c`` over ``cyclic_pump.c``, whose header explains the design), for a
machine where the extension cannot be loaded (``cobot_hmi.native`` picks it then, and says so
in the log) and for tests and benches that force it (``COBOT_HMI_PUMP=python``).

The thread keeps the same schedule: it sleeps in a :class:`PreciseEpollSelector` (a timerfd
gives it microsecond wake-ups) until the next datagram is due, sends it, and reads the socket
into the ring with the kernel's receive times. What it cannot match is the cost: each of its
wake-ups runs Python and must take the GIL, which another thread may hold for up to the
interpreter's switch interval (5 ms); so at a 2 ms RPI packets leave later and less evenly than
from the C thread, and it costs the process more CPU. At 10 ms (the service's default) it keeps
the RPI (docs/protocol.md, "Timing").

Thread safety: one lock guards everything the thread and the callers share, as in the C
pump; the thread holds it only between waits.
"""

from __future__ import annotations

import bisect
import contextlib
import os
import selectors
import socket
import struct
import threading
import time
import weakref
from collections import deque
from dataclasses import dataclass, field
from types import TracebackType
from typing import Final

from cobot_hmi.eventloop import PreciseEpollSelector

NEVER: Final = 2**63 - 1
TAKE_MAX: Final = 64
_SO_TIMESTAMPNS: Final = getattr(socket, "SO_TIMESTAMPNS", 35)  # asm-generic/socket.h
_TIMESPEC: Final = struct.Struct("@ll")
_ANCILLARY_BYTES: Final = socket.CMSG_SPACE(_TIMESPEC.size)
_DRAIN_MAX: Final = 1024
PERIODIC_MAX: Final = 64
"""Periodic streams at once, as the C pump's ``PUMP_PERIODIC_MAX`` (cyclic_pump.h)."""
PUMP_FIFO_PRIORITY: Final = 10  # cyclic_pump.c's: low among real-time priorities


@dataclass(slots=True)
class _Periodic:
    tag: int
    due_ns: int
    period_ns: int
    addr: tuple[str, int]
    data: bytearray
    off32: int
    off16: int
    count32: int
    count16: int


@dataclass(order=True, slots=True)
class _Queued:
    due_ns: int
    order: int  # equal due times leave in the order they were queued
    tag: int = field(compare=False)
    addr: tuple[str, int] = field(compare=False)
    data: bytes = field(compare=False)


def _ip_text(ip: int) -> str:
    return socket.inet_ntoa(ip.to_bytes(4, "big"))


class _State:
    """What the thread and the callers share, behind ``lock``."""

    def __init__(
        self, fd: int, queue_cap: int, queue_bytes: int, ring_cap: int, ring_bytes: int
    ) -> None:
        self.sock = socket.socket(fileno=os.dup(fd))  # its own descriptor, closed with us
        self.sock.setblocking(False)
        self.queue_cap, self.queue_bytes = queue_cap, queue_bytes
        self.ring_cap, self.ring_bytes = ring_cap, ring_bytes
        self.lock = threading.Lock()
        self.running = True
        self.close_on_exit = False  # stopped from this very thread (see _stop)
        self.kick_fd = os.eventfd(0, os.EFD_NONBLOCK | os.EFD_CLOEXEC)
        self.notify_fd = os.eventfd(0, os.EFD_NONBLOCK | os.EFD_CLOEXEC)
        self.queue: list[_Queued] = []  # kept sorted by due time
        self.order = 0
        self.periodics: dict[int, _Periodic] = {}
        self.ring: deque[tuple[bytes, int, int, int]] = deque()
        self.read_on_readable = False
        self.notify_interval_ns = 0
        self.silence_ns = 0
        self.last_rx_ns = 0
        self.silence_reported = False
        self.last_notify_ns = -NEVER
        self.notified = False
        self.sleeping_until = NEVER
        # sent, send errors, received, ring overflows, wake-ups, max late (ns), real-time priority
        self.counters = [0] * 7
        self.addresses: dict[tuple[int, int], tuple[str, int]] = {}
        self.sources: dict[str, int] = {}

    # ---------------------------------------------------------------- the thread (lock held)

    def kick(self) -> None:
        with contextlib.suppress(BlockingIOError):
            os.eventfd_write(self.kick_fd, 1)

    def address(self, ip: int, port: int) -> tuple[str, int]:
        addr = self.addresses.get((ip, port))
        if addr is None:
            addr = (_ip_text(ip), port)
            if len(self.addresses) < 4096:
                self.addresses[(ip, port)] = addr
        return addr

    def send_one(
        self, data: bytes | bytearray, addr: tuple[str, int], due_ns: int, now: int
    ) -> None:
        try:
            self.sock.sendto(data, socket.MSG_DONTWAIT, addr)
        except OSError:
            self.counters[1] += 1
            return
        self.counters[0] += 1
        self.counters[5] = max(self.counters[5], now - due_ns)

    def send_due(self, now: int) -> int:
        """Send what is due; when the next send is due (NEVER: nothing left)."""
        next_ns = NEVER
        for s in self.periodics.values():
            if s.due_ns <= now:
                if s.off32 >= 0:
                    s.data[s.off32 : s.off32 + 4] = s.count32.to_bytes(4, "little")
                if s.off16 >= 0:
                    s.data[s.off16 : s.off16 + 2] = s.count16.to_bytes(2, "little")
                self.send_one(s.data, s.addr, s.due_ns, now)
                s.count32 = (s.count32 + 1) & 0xFFFFFFFF
                s.count16 = (s.count16 + 1) & 0xFFFF
                s.due_ns += s.period_ns
                if s.due_ns < now - s.period_ns:  # stalled: one catch-up, on the stream's grid
                    s.due_ns += (now - s.due_ns) // s.period_ns * s.period_ns
            next_ns = min(next_ns, s.due_ns)
        queue = self.queue
        sent = 0
        for item in queue:
            if item.due_ns > now:
                next_ns = min(next_ns, item.due_ns)
                break
            self.send_one(item.data, item.addr, item.due_ns, now)
            sent += 1
        del queue[:sent]
        return next_ns

    def drain_socket(self) -> None:
        mono_minus_real = time.monotonic_ns() - time.time_ns()
        ring, sources = self.ring, self.sources
        for _ in range(_DRAIN_MAX):
            try:
                data, ancillary, _flags, source = self.sock.recvmsg(
                    self.ring_bytes, _ANCILLARY_BYTES, socket.MSG_DONTWAIT
                )
            except BlockingIOError:
                return
            except OSError:
                continue  # an ICMP error reported on the socket: not a datagram
            stamp = -1
            for level, kind, value in ancillary:
                if level == socket.SOL_SOCKET and kind == _SO_TIMESTAMPNS:
                    seconds, nanoseconds = _TIMESPEC.unpack_from(value)
                    stamp = seconds * 1_000_000_000 + nanoseconds + mono_minus_real
            if stamp < 0:
                stamp = time.monotonic_ns()
            # Never backwards (as the C pump): the offset above is read from two clocks one
            # after the other, and a thread preempted between them shifts it by microseconds.
            stamp = max(stamp, self.last_rx_ns)
            host, port = source
            ip = sources.get(host)
            if ip is None:
                ip = int.from_bytes(socket.inet_aton(host), "big")
                if len(sources) < 4096:  # a flood of forged sources must not grow it forever
                    sources[host] = ip
            # Cut to the slot (MSG_TRUNC): exactly ring_bytes long, so seen as too long.
            if len(ring) == self.ring_cap:
                ring.popleft()
                self.counters[3] += 1
            ring.append((data, ip, port, stamp))
            self.last_rx_ns = stamp
            self.silence_reported = False
            self.counters[2] += 1

    def notify(self) -> None:
        with contextlib.suppress(BlockingIOError):
            os.eventfd_write(self.notify_fd, 1)
        self.notified = True

    def run(self) -> None:
        # As the C thread: real-time priority when the system grants it (pid 0: this thread).
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(PUMP_FIFO_PRIORITY))
            realtime = 1
        except (OSError, AttributeError):
            realtime = 0
        with self.lock:
            self.counters[6] = realtime
        selector = PreciseEpollSelector()
        selector.register(self.kick_fd, selectors.EVENT_READ)
        socket_watched = False
        woke = 0
        try:
            while self.running:
                with self.lock:
                    self.counters[4] += woke
                    woke = 1
                    now = time.monotonic_ns()
                    next_ns = self.send_due(now)
                    self.drain_socket()
                    sending = next_ns != NEVER
                    if self.ring and not self.notified and self.notify_interval_ns >= 0:
                        notify_at = self.last_notify_ns + self.notify_interval_ns
                        if notify_at <= now:
                            self.notify()
                            self.last_notify_ns = now
                        elif next_ns == NEVER or next_ns - notify_at > self.notify_interval_ns:
                            next_ns = notify_at
                    if self.silence_ns > 0 and self.last_rx_ns > 0 and not self.silence_reported:
                        quiet_until = self.last_rx_ns + self.silence_ns
                        if quiet_until <= now:
                            self.notify()
                            self.silence_reported = True
                        elif quiet_until < next_ns:
                            next_ns = quiet_until
                    self.sleeping_until = next_ns
                    watch_socket = self.read_on_readable or not sending
                if watch_socket != socket_watched:
                    if watch_socket:
                        selector.register(self.sock.fileno(), selectors.EVENT_READ)
                    else:
                        selector.unregister(self.sock.fileno())
                    socket_watched = watch_socket
                timeout_s = None
                if next_ns != NEVER:
                    timeout_s = max(0, next_ns - time.monotonic_ns()) * 1e-9
                for key, _ in selector.select(timeout_s):
                    if key.fd == self.kick_fd:
                        with contextlib.suppress(BlockingIOError):
                            os.eventfd_read(self.kick_fd)
        finally:
            selector.close()
            if self.close_on_exit:
                self.close()

    def close(self) -> None:
        self.sock.close()
        os.close(self.kick_fd)
        os.close(self.notify_fd)


def _stop(state: _State, thread: threading.Thread) -> None:
    """Stop and join the thread, then close what it used (the finalizer: holds no Pump).

    Without the lock: the garbage collector may run this in any thread, the pump's own included,
    maybe while that thread holds the lock (a bool's assignment is atomic under the GIL). In the
    pump's own thread it cannot join itself: the thread closes what it used as it ends."""
    state.running = False
    if thread is threading.current_thread():
        state.close_on_exit = True
        return
    state.kick()
    if thread.is_alive():
        thread.join()
    state.close()


class Pump:
    """The cyclic pump of one UDP socket, as ``_cyclic_pump.Pump`` (its stub types both)."""

    def __init__(
        self, fd: int, queue_cap: int, queue_bytes: int, ring_cap: int, ring_bytes: int
    ) -> None:
        if fd < 0 or min(queue_cap, queue_bytes, ring_cap, ring_bytes) <= 0:
            raise ValueError("a pump needs a socket and positive sizes")
        state = self._state = _State(fd, queue_cap, queue_bytes, ring_cap, ring_bytes)
        thread = threading.Thread(target=state.run, name="cyclic-pump", daemon=True)
        thread.start()
        # A pump dropped unclosed stops its thread: the thread holds only the state.
        self._finalizer = weakref.finalize(self, _stop, state, thread)

    def _live(self) -> _State:
        if not self._finalizer.alive:
            raise ValueError("the cyclic pump is closed")
        return self._state

    def close(self) -> None:
        self._finalizer()

    def __enter__(self) -> Pump:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.close()

    def notify_fd(self) -> int:
        return self._live().notify_fd

    def configure(self, read_on_readable: bool, notify_interval_ns: int, silence_ns: int) -> None:
        state = self._live()
        with state.lock:
            state.read_on_readable = read_on_readable
            state.notify_interval_ns = notify_interval_ns
            state.silence_ns = silence_ns
        state.kick()

    def queue(self, due_ns: int, ip: int, port: int, data: bytes, tag: int) -> int:
        state = self._live()
        if len(data) > state.queue_bytes:
            return -2
        with state.lock:
            if len(state.queue) >= state.queue_cap:
                return -1
            state.order += 1
            item = _Queued(due_ns, state.order, tag, state.address(ip, port), bytes(data))
            bisect.insort(state.queue, item)
            wake = due_ns < state.sleeping_until
            if wake:
                state.sleeping_until = due_ns
        if wake:
            state.kick()
        return 0

    def cancel(self, tag: int, from_ns: int) -> tuple[int, int]:
        state = self._live()
        with state.lock:
            kept, first_due = [], 0
            removed = 0
            for item in state.queue:
                if (tag < 0 or item.tag == tag) and item.due_ns >= from_ns:
                    if removed == 0 or item.due_ns < first_due:
                        first_due = item.due_ns
                    removed += 1
                else:
                    kept.append(item)
            state.queue[:] = kept
        return removed, first_due

    def queued(self, tag: int) -> int:
        state = self._live()
        with state.lock:
            return sum(1 for item in state.queue if item.tag == tag)

    def take(self, drain_first: bool, max_count: int) -> list[tuple[bytes, int, int, int]]:
        state = self._live()
        with state.lock:
            if drain_first:
                state.drain_socket()
            ring = state.ring
            taken = [ring.popleft() for _ in range(min(max(max_count, 0), TAKE_MAX, len(ring)))]
            if not ring and state.notified:
                with contextlib.suppress(BlockingIOError):
                    os.eventfd_read(state.notify_fd)
                state.notified = False
        return taken

    def counters(self) -> tuple[int, int, int, int, int, int, int]:
        state = self._live()
        with state.lock:
            c = state.counters
            return c[0], c[1], c[2], c[3], c[4], c[5], c[6]

    def periodic_start(  # noqa: PLR0917
        self,
        tag: int,
        first_due_ns: int,
        period_ns: int,
        ip: int,
        port: int,
        data: bytes,
        off32: int,
        first32: int,
        off16: int,
        first16: int,
    ) -> int:
        state = self._live()
        if len(data) > state.queue_bytes or off32 + 4 > len(data) or off16 + 2 > len(data):
            return -2
        if period_ns <= 0:
            return -2
        with state.lock:
            if tag not in state.periodics and len(state.periodics) >= PERIODIC_MAX:
                return -1
            state.periodics[tag] = _Periodic(
                tag,
                first_due_ns,
                period_ns,
                state.address(ip, port),
                bytearray(data),
                off32,
                off16,
                first32 & 0xFFFFFFFF,
                first16 & 0xFFFF,
            )
            wake = first_due_ns < state.sleeping_until
            if wake:
                state.sleeping_until = first_due_ns
        if wake:
            state.kick()
        return 0

    def periodic_data(self, tag: int, data: bytes) -> int:
        state = self._live()
        with state.lock:
            stream = state.periodics.get(tag)
            if stream is None:
                return -1
            if len(data) > state.queue_bytes or stream.off32 + 4 > len(data):
                return -2
            if stream.off16 + 2 > len(data):
                return -2
            stream.data = bytearray(data)
            return 0

    def periodic_next(self, tag: int, stop: bool) -> tuple[int, int, int] | None:
        state = self._live()
        with state.lock:
            stream = state.periodics.get(tag)
            if stream is None:
                return None
            if stop:
                del state.periodics[tag]
            return stream.count32, stream.count16, stream.due_ns


__all__ = ["PERIODIC_MAX", "TAKE_MAX", "Pump"]

"""Layer: runtime support for the I/O layers (emulator, scanner, service) and the pure-Python
cyclic pump (``native.pure``). Imports nothing of the project.

Every event loop of the product waits in ``epoll_wait``: no ceiling on file descriptor numbers
(``select()`` refuses any fd above 1023, and a service with a thousand clients and log files
has such fds; the loop's thread would die of "filedescriptor out of range"). But epoll's
timeout is in whole milliseconds (CPython rounds every wait up to the next one), and the class
1 owners' timers (a batch at 40 ms, a packet built each RPI at 10 ms and longer) would then fire
up to 1 ms late. :class:`PreciseEpollSelector` keeps the microseconds: a ``timerfd`` (Linux's
timer as a file descriptor, nanosecond resolution) in the same epoll set, armed for each wait
with its exact timeout, wakes the wait on time; epoll's own, rounded-up timeout only backs it.
One ``timerfd_settime`` call per wait (through ctypes: Python 3.11's ``os`` lacks timerfd)
against a wake-up of 60-100 µs is nothing. The loop's thread also gets a 1 µs timer slack
(Linux's default, 50 µs, would be jitter for nothing). Periodic senders schedule absolute loop
times (``loop.call_at(deadline)``, ``deadline += period``), so they stay drift-free instead of
accumulating ``sleep(period)`` errors. The packets themselves are timed by the cyclic pump's own
thread (``native``), not by this loop.

:func:`freeze_startup_heap` keeps the cyclic garbage collector from stalling such a schedule,
and from spending a process's CPU on objects that live a frame's way through it.
"""

from __future__ import annotations

import asyncio
import contextlib
import ctypes
import gc
import os
import select
import selectors
import sys
from collections.abc import Iterator, Mapping
from typing import TYPE_CHECKING, Any, Final

if TYPE_CHECKING:
    from _typeshed import FileDescriptorLike

_CLOCK_MONOTONIC: Final = 1  # linux/time.h: asyncio's loop.time() is time.monotonic()
_TFD_FLAGS: Final = os.O_NONBLOCK | os.O_CLOEXEC  # TFD_NONBLOCK, TFD_CLOEXEC (linux/timerfd.h)


class _Timespec(ctypes.Structure):
    _fields_ = (("tv_sec", ctypes.c_long), ("tv_nsec", ctypes.c_long))


class _Itimerspec(ctypes.Structure):
    _fields_ = (("it_interval", _Timespec), ("it_value", _Timespec))


class _Timerfd:
    """A one-shot CLOCK_MONOTONIC timerfd, armed with a relative timeout."""

    def __init__(self) -> None:
        libc = ctypes.CDLL(None, use_errno=True)
        self._create = libc.timerfd_create
        self._create.argtypes = (ctypes.c_int, ctypes.c_int)
        self._create.restype = ctypes.c_int
        self._settime = libc.timerfd_settime
        self._settime.argtypes = (
            ctypes.c_int,
            ctypes.c_int,
            ctypes.POINTER(_Itimerspec),
            ctypes.c_void_p,
        )
        self._settime.restype = ctypes.c_int
        fd = self._create(_CLOCK_MONOTONIC, _TFD_FLAGS)
        if fd < 0:
            raise OSError(ctypes.get_errno(), "timerfd_create")
        self.fd: int = fd
        self._spec = _Itimerspec()
        self._value = self._spec.it_value
        self.armed = False

    def arm(self, timeout_ns: int) -> None:
        """Fire once, ``timeout_ns`` from now (at least 1 ns: 0 would disarm it)."""
        self._value.tv_sec, self._value.tv_nsec = divmod(max(timeout_ns, 1), 1_000_000_000)
        self._settime(self.fd, 0, self._spec, None)
        self.armed = True

    def disarm(self) -> None:
        self._value.tv_sec = self._value.tv_nsec = 0
        self._settime(self.fd, 0, self._spec, None)
        self.armed = False

    def consume(self) -> None:
        """It fired: read the expiry count, or it would stay readable."""
        self.armed = False
        with contextlib.suppress(BlockingIOError):
            os.read(self.fd, 8)

    def close(self) -> None:
        os.close(self.fd)


def _new_timerfd() -> _Timerfd | None:
    if sys.platform != "linux":
        return None
    try:
        return _Timerfd()
    except (OSError, AttributeError):  # no timerfd: epoll's millisecond rounding it is
        return None


def _fd(fileobj: FileDescriptorLike) -> int:
    fd = fileobj if isinstance(fileobj, int) else int(fileobj.fileno())
    if fd < 0:
        raise ValueError(f"invalid file descriptor: {fd}")
    return fd


class _KeyMap(Mapping["FileDescriptorLike", selectors.SelectorKey]):
    """The selector's keys by file object or descriptor (``BaseSelector.get_map``)."""

    def __init__(self, keys: dict[int, selectors.SelectorKey]) -> None:
        self._keys = keys

    def __len__(self) -> int:
        return len(self._keys)

    def __iter__(self) -> Iterator[FileDescriptorLike]:
        return iter(self._keys)

    def __getitem__(self, fileobj: FileDescriptorLike) -> selectors.SelectorKey:
        return self._keys[_fd(fileobj)]


class PreciseEpollSelector(selectors.BaseSelector):
    """An epoll selector whose timeouts keep their microseconds (see the module's docstring).
    Without timerfd (not Linux) it waits with epoll's millisecond rounding."""

    def __init__(self) -> None:
        self._epoll = select.epoll()
        self._keys: dict[int, selectors.SelectorKey] = {}
        self._map = _KeyMap(self._keys)
        self._timer = _new_timerfd()
        self._timer_fd = -1
        if self._timer is not None:
            self._timer_fd = self._timer.fd
            self._epoll.register(self._timer_fd, select.EPOLLIN)

    @staticmethod
    def _mask(events: int) -> int:
        if not events or events & ~(selectors.EVENT_READ | selectors.EVENT_WRITE):
            raise ValueError(f"invalid events: {events!r}")
        mask = 0
        if events & selectors.EVENT_READ:
            mask |= select.EPOLLIN
        if events & selectors.EVENT_WRITE:
            mask |= select.EPOLLOUT
        return mask

    def register(
        self, fileobj: FileDescriptorLike, events: int, data: Any = None
    ) -> selectors.SelectorKey:
        fd = _fd(fileobj)
        mask = self._mask(events)
        if fd in self._keys:
            raise KeyError(f"{fileobj!r} (FD {fd}) is already registered")
        self._epoll.register(fd, mask)
        key = self._keys[fd] = selectors.SelectorKey(fileobj, fd, events, data)
        return key

    def unregister(self, fileobj: FileDescriptorLike) -> selectors.SelectorKey:
        fd = _fd(fileobj)
        try:
            key = self._keys.pop(fd)
        except KeyError:
            raise KeyError(f"{fileobj!r} is not registered") from None
        # Closed before it was unregistered: epoll forgot it already.
        with contextlib.suppress(OSError):
            self._epoll.unregister(fd)
        return key

    def modify(
        self, fileobj: FileDescriptorLike, events: int, data: Any = None
    ) -> selectors.SelectorKey:
        fd = _fd(fileobj)
        try:
            key = self._keys[fd]
        except KeyError:
            raise KeyError(f"{fileobj!r} is not registered") from None
        if events != key.events:
            self._epoll.modify(fd, self._mask(events))
        key = self._keys[fd] = key._replace(events=events, data=data)
        return key

    def get_map(self) -> Mapping[FileDescriptorLike, selectors.SelectorKey]:
        return self._map

    def select(self, timeout: float | None = None) -> list[tuple[selectors.SelectorKey, int]]:
        timer = self._timer
        if timeout is None:
            wait_s = -1.0
            if timer is not None and timer.armed:
                timer.disarm()  # a stale expiry would wake the endless wait for nothing
        elif timeout <= 0:
            wait_s = 0.0
        else:
            wait_s = timeout  # epoll rounds it up to whole ms: the timer (exact) comes first
            if timer is not None:
                timer.arm(round(timeout * 1e9))
        keys = self._keys
        try:
            fd_events = self._epoll.poll(wait_s, len(keys) + 1)
        except InterruptedError:
            return []
        ready: list[tuple[selectors.SelectorKey, int]] = []
        for fd, event in fd_events:
            key = keys.get(fd)
            if key is None:
                if fd == self._timer_fd and timer is not None:
                    timer.consume()
                continue
            events = 0
            if event & ~select.EPOLLIN:
                events |= selectors.EVENT_WRITE
            if event & ~select.EPOLLOUT:
                events |= selectors.EVENT_READ
            ready.append((key, events & key.events))
        return ready

    def close(self) -> None:
        self._keys.clear()
        self._epoll.close()
        if self._timer is not None:
            self._timer.close()
            self._timer = None


def precise_event_loop() -> asyncio.AbstractEventLoop:
    """A new epoll event loop whose timers fire with sub-millisecond precision. Create it in
    the thread that runs it: that thread's timer slack is tightened too."""
    _tighten_timer_slack()
    return asyncio.SelectorEventLoop(PreciseEpollSelector())


_PR_SET_TIMERSLACK = 29  # linux/prctl.h
_TIMER_SLACK_NS = 1_000


def _tighten_timer_slack() -> None:
    """Linux lets a sleeping thread's timer fire up to its "timer slack" late (50 µs by
    default) to batch wake-ups; for a 2 ms RPI that is jitter for nothing. 1 µs instead, for
    the calling thread (the loop's). Best effort: elsewhere, or if refused, nothing changes."""
    if sys.platform != "linux":
        return
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_TIMERSLACK, ctypes.c_ulong(_TIMER_SLACK_NS), 0, 0, 0)
    except (OSError, AttributeError):
        pass


YOUNG_COLLECTION_THRESHOLD: Final = 50_000
"""Net allocations of tracked objects between two collections of the youngest generation
(CPython's default: 700). A frame's objects (its record in each consumer's queue, the lists and
values a consumer builds of it) live from a few milliseconds to a second (health's batch), and
a cell of 32 robots makes them in bursts of thousands per batch: at 700 the collector ran about
15 times a second, each time walking that batch alive, moving it to the older generations, whose
collections then walked it again, and the whole heap left unfrozen (the OPC UA historian's
monitored items) 0.2 s at a time about every 14 s: bench/fanout at 32 robots with every door
counted 4.9 s of the service's CPU in collections over 124 s (some 13 µs per robot-frame).
At 50 000 most of those objects are gone before a collection looks (reference counting frees
them): 5 collections of the youngest generation in 107 s, 0.23 s in all, none older. Reference
cycles are still collected, later; each collection holds the GIL about 60 ms there, which no
packet waits for (the pump's thread times them)."""


def freeze_startup_heap() -> None:
    """Exempt every object alive now from the cyclic garbage collector's full collections.

    Call once, after start-up, in a process that holds class 1 timing. A full (generation 2)
    collection walks every tracked object of the process: with FastAPI, uvicorn and the rest
    imported, some 50 000 of them, 15-30 ms during which nothing else runs, about the whole
    watchdog of a 2 ms RPI connection (RPI × 16 = 32 ms). What exists after start-up (modules,
    classes, the app) lives as long as the process, so walking it again finds nothing;
    ``gc.freeze`` moves it to a permanent generation the collector no longer visits, and later
    collections only walk what was made since. Reference counting still frees everything else
    at once, and new cycles are still collected. Then the youngest generation is collected
    less often (``YOUNG_COLLECTION_THRESHOLD``).
    """
    gc.collect()
    gc.freeze()
    gc.set_threshold(YOUNG_COLLECTION_THRESHOLD, *gc.get_threshold()[1:])

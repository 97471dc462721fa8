"""Layer: runtime support for the I/O layers (emulator, scanner, service). Imports nothing of
the project.

Class 1 traffic runs on a schedule of a few milliseconds. The default asyncio loop on Linux
waits in ``epoll_wait``, whose timeout has a resolution of one millisecond (CPython rounds
every wait up to the next whole millisecond), so a 2 ms RPI would jitter by up to 1 ms.
``select()`` takes its timeout in microseconds: a loop built on ``SelectSelector`` wakes within
the kernel's timer slack instead, which the loop's thread sets to 1 µs (Linux's default, 50 µs,
would be jitter for nothing). It handles a few dozen sockets, which is all either role opens.
Periodic senders schedule absolute loop times (``loop.call_at(deadline)``, ``deadline +=
period``), so they stay drift-free instead of accumulating ``sleep(period)`` errors.

:func:`freeze_startup_heap` keeps the cyclic garbage collector from stalling such a schedule.
"""

from __future__ import annotations

import asyncio
import ctypes
import gc
import selectors
import sys


def precise_event_loop() -> asyncio.AbstractEventLoop:
    """A new event loop whose timers fire with sub-millisecond precision. Create it in the
    thread that runs it: that thread's timer slack is tightened too."""
    _tighten_timer_slack()
    return asyncio.SelectorEventLoop(selectors.SelectSelector())


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


def freeze_startup_heap() -> None:
    """Exempt every object alive now from the cyclic garbage collector's full collections.

    Call once, after start-up, in a process that holds class 1 timing. A full (generation 2)
    collection walks every tracked object of the process: with FastAPI, uvicorn and the rest
    imported, some 50 000 of them, 15-30 ms during which nothing else runs, about the whole
    watchdog of a 2 ms RPI connection (RPI × 16 = 32 ms). What exists after start-up (modules,
    classes, the app) lives as long as the process, so walking it again finds nothing;
    ``gc.freeze`` moves it to a permanent generation the collector no longer visits, and later
    collections only walk what was made since. Reference counting still frees everything else
    at once, and new cycles are still collected.
    """
    gc.collect()
    gc.freeze()

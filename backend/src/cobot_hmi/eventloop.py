"""Layer: runtime support for the I/O layers (emulator, scanner, service). Imports nothing of
the project.

Class 1 traffic runs on a schedule of a few milliseconds. The default asyncio loop on Linux
waits in ``epoll_wait``, whose timeout has a resolution of one millisecond (CPython rounds
every wait up to the next whole millisecond), so a 2 ms RPI would jitter by up to 1 ms.
``select()`` takes its timeout in microseconds: a loop built on ``SelectSelector`` wakes within
the kernel's timer slack instead. It handles a few dozen sockets, which is all either role
opens. :func:`sleep_until` sleeps to an absolute loop time, so a periodic sender keeps a
drift-free schedule (``deadline += period``) instead of accumulating ``sleep(period)`` errors.
"""

from __future__ import annotations

import asyncio
import selectors


def precise_event_loop() -> asyncio.AbstractEventLoop:
    """A new event loop whose timers fire with sub-millisecond precision."""
    return asyncio.SelectorEventLoop(selectors.SelectSelector())


async def sleep_until(deadline: float) -> None:
    """Sleep until ``loop.time()`` reaches ``deadline`` (returns at once if it has)."""
    loop = asyncio.get_running_loop()
    if deadline <= loop.time():
        await asyncio.sleep(0)
        return
    future: asyncio.Future[None] = loop.create_future()
    handle = loop.call_at(deadline, _wake, future)
    try:
        await future
    finally:
        handle.cancel()


def _wake(future: asyncio.Future[None]) -> None:
    if not future.done():
        future.set_result(None)

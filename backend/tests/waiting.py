"""Waiting for a condition, the one way the tests wait (never a sleep that hopes it is long
enough). The deadline only bounds how long a broken test takes to fail: a passing test never
waits for it, so it is wide enough that no load on a shared machine exhausts it."""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable

WAIT_DEADLINE_S = 30.0
POLL_S = 0.01


async def eventually(check: Callable[[], object], timeout_s: float = WAIT_DEADLINE_S) -> None:
    """Until ``check()`` is truthy (a functional deadline, not a timing figure)."""
    loop = asyncio.get_running_loop()
    end = loop.time() + timeout_s
    while not check():
        assert loop.time() < end, "condition not reached in time"
        await asyncio.sleep(POLL_S)


async def eventually_async(
    check: Callable[[], Awaitable[object]], timeout_s: float = WAIT_DEADLINE_S
) -> None:
    """``eventually`` for a check that awaits (an HTTP request, say)."""
    loop = asyncio.get_running_loop()
    end = loop.time() + timeout_s
    while not await check():
        assert loop.time() < end, "condition not reached in time"
        await asyncio.sleep(POLL_S)

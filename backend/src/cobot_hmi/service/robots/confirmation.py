"""Layer: service. Write confirmation: the first frame after a write that shows what it asked.

``FrameWaiters`` is one robot's frame consumer (``robots.frame_notifier``) on the web loop. A write
(``writes.pipeline``) waits in ``wait_for_frame`` for the first frame newer than the one before
its O→T image changed for which its predicate holds. While anyone waits the consumer is
``urgent``: the notifier wakes the loop on every frame instead of every ``frames_per_wake``, so
a confirmation costs one RPI, not a broadcast period; with no one waiting it costs nothing.

Must not import the web layer or the scanner.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable, Sequence
from typing import Final

from cobot_hmi.codec import Frame
from cobot_hmi.service.robots.frame_notifier import FrameNotifier, FrameRecord, Registration, Runs

QUEUE_FRAMES: Final = 64
"""Frames kept between two turns (a confirmation needs the newest few)."""


class _Waiter:
    __slots__ = ("after_seq", "future", "predicate")

    def __init__(
        self,
        after_seq: int,
        predicate: Callable[[Frame], bool],
        future: asyncio.Future[FrameRecord],
    ) -> None:
        self.after_seq = after_seq
        self.predicate = predicate
        self.future = future


class FrameWaiters:
    """Writes waiting for a frame (see the module docstring)."""

    name: Final = "write-confirmation"
    runs: Final = Runs.LOOP
    queue_frames: Final = QUEUE_FRAMES

    def __init__(self, notifier: FrameNotifier) -> None:
        self._notifier = notifier
        self._waiters: list[_Waiter] = []
        self._registration: Registration = notifier.add(self)

    def on_frames(self, robot: str, records: Sequence[FrameRecord]) -> None:
        if self._waiters:
            self._check(records)

    def _check(self, records: Sequence[FrameRecord]) -> None:
        still = []
        for waiter in self._waiters:
            if waiter.future.done():
                continue
            for record in records:
                if record.seq > waiter.after_seq and waiter.predicate(record.frame):
                    waiter.future.set_result(record)
                    break
            else:
                still.append(waiter)
        self._waiters = still
        self._registration.urgent = bool(still)

    async def wait_for_frame(
        self, predicate: Callable[[Frame], bool], after_seq: int, timeout_s: float
    ) -> FrameRecord | None:
        """The first frame newer than ``after_seq`` for which ``predicate`` holds, or ``None``
        after ``timeout_s``."""
        waiter = _Waiter(after_seq, predicate, asyncio.get_running_loop().create_future())
        self._waiters.append(waiter)
        self._registration.urgent = True
        latest = self._notifier.latest  # it may be here already
        if latest is not None:
            self._check([latest])
        try:
            async with asyncio.timeout(timeout_s):
                return await waiter.future
        except TimeoutError:
            return None
        finally:
            if waiter in self._waiters:
                self._waiters.remove(waiter)
            self._registration.urgent = bool(self._waiters)

    def close(self) -> None:
        for waiter in self._waiters:
            waiter.future.cancel()
        self._waiters.clear()
        self._registration.urgent = False

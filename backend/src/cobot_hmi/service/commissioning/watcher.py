"""Layer: service. The checkout's consumer of a robot's frames (``robots.frame_notifier``), on
the web event loop: while a checkout of the robot is open, every frame goes through
``CheckoutWatcher.on_frames``, and a digital input (DI, Tool DI, bit output register) whose
value changes from one frame to the next is marked ``seen`` in every open checkout where it has
not been seen yet, with that frame's receive time, its number and both values; nobody needs to
touch the screen. The points that changed are then saved (one task per batch, in order).

Registered with the robot's ``FrameNotifier`` only while the robot has an open checkout
(``update``); the frame's own time and number are recorded, so how late a batch is handed
over changes nothing of what is kept.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Sequence
from typing import Final

from cobot_hmi.codec import Frame
from cobot_hmi.service.commissioning.checkout import Checkout, CheckoutBook, PointState
from cobot_hmi.service.commissioning.points import DIGITAL_INPUT_FIELDS
from cobot_hmi.service.robots.frame_notifier import FrameNotifier, FrameRecord, Registration, Runs

log = logging.getLogger(__name__)

QUEUE_FRAMES: Final = 4096
"""Frames the loop may fall behind by before the oldest are lost (~40 s at 10 ms)."""


class CheckoutWatcher:
    """One robot's frames to its open checkouts (see the module docstring)."""

    name: Final = "checkout"
    runs: Final = Runs.LOOP
    queue_frames: Final = QUEUE_FRAMES

    def __init__(self, book: CheckoutBook, frames: FrameNotifier) -> None:
        self.book = book
        self.frames = frames
        self._registration: Registration | None = None
        self._previous: Frame | None = None
        self._saving: asyncio.Task[None] | None = None

    def update(self) -> None:
        """Watch while the robot has an open checkout, stop when it has none."""
        if self.book.open and self._registration is None:
            latest = self.frames.latest
            self._previous = None if latest is None else latest.frame
            self._registration = self.frames.add(self)
        elif not self.book.open and self._registration is not None:
            self.frames.remove(self._registration)
            self._registration = None

    async def stop(self) -> None:
        """Stop watching; the last changes saved."""
        if self._registration is not None:
            self.frames.remove(self._registration)
            self._registration = None
        if self._saving is not None:
            await asyncio.gather(self._saving, return_exceptions=True)

    def on_frames(self, robot: str, records: Sequence[FrameRecord]) -> None:
        changed: dict[int, list[PointState]] = {}
        for record in records:
            self.observe(record.frame, record.received_at_s, record.seq, changed)
        if changed:
            self._saving = asyncio.get_running_loop().create_task(
                self._save(self._saving, changed), name=f"checkout save {robot}"
            )

    async def _save(
        self, before: asyncio.Task[None] | None, changed: dict[int, list[PointState]]
    ) -> None:
        if before is not None:  # in order: a point's newer state is never overwritten
            await asyncio.gather(before, return_exceptions=True)
        for checkout_id, states in changed.items():
            checkout = self.book.open.get(checkout_id)
            if checkout is None:
                continue
            try:
                await self.book.save(checkout, states)
            except Exception:  # kept in memory: the next change of the point saves it again
                log.exception("%s: checkout %d: points not saved", self.book.robot, checkout_id)

    def observe(
        self, frame: Frame, received_at: float, seq: int, changed: dict[int, list[PointState]]
    ) -> None:
        """One frame: the inputs it changed marked seen (``changed`` collects them)."""
        previous, self._previous = self._previous, frame
        if previous is None:
            return
        for name in DIGITAL_INPUT_FIELDS:
            now = getattr(frame, name)
            before = getattr(previous, name)
            if now == before:  # the usual case: one tuple comparison per field
                continue
            for index, (old, new) in enumerate(zip(before, now, strict=True)):
                if old != new:
                    key = f"{name}.{index}"
                    for checkout in self.book.open.values():
                        _mark(
                            checkout,
                            key,
                            received_at=received_at,
                            seq=seq,
                            before=old,
                            after=new,
                            changed=changed,
                        )


def _mark(
    checkout: Checkout,
    key: str,
    *,
    received_at: float,
    seq: int,
    before: object,
    after: object,
    changed: dict[int, list[PointState]],
) -> None:
    state = checkout.points.get(key)
    if state is None or state.seen is not None:
        return
    state.seen = {"time": received_at, "seq": seq, "before": before, "after": after}
    if state.result == "untested":
        state.result = "seen"
    changed.setdefault(checkout.id, []).append(state)

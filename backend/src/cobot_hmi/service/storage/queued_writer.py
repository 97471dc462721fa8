"""Layer: service. One writer task for rows that are queued where they happen (the frame path
never waits on the disk) and written a batch per transaction: the events, the alarm
transitions, the measured cycles. Imports nothing of the project.

A batch that cannot be written for want of the disk (``sqlite3.OperationalError``: a full
disk, above all) is not dropped: it waits in memory, oldest first, and is tried again every
``retry_s``; rows that come meanwhile join it rather than being tried on their own (a full disk
does not cost a failed transaction per event). So what happened reaches the database in the
order it happened once the disk has room. Only beyond ``limit`` waiting rows are the oldest
given up (counted in ``lost`` and logged), so a disk that stays full costs bounded memory; what
still waits when the writer closes is lost too, and said so. Any other error is a bug of the
rows: that batch is logged and given up, so it cannot hold back the rows after it.
"""

from __future__ import annotations

import asyncio
import logging
import sqlite3
import time
from collections.abc import Awaitable, Callable
from typing import Final, Generic, TypeVar

log = logging.getLogger(__name__)

T = TypeVar("T")

RETRY_S: Final = 1.0
"""How often rows that wait are tried again."""
WAITING_MAX: Final = 10_000
"""Rows kept in memory while they cannot be written (about 1 to 5 MB of the service's)."""


class QueuedWriter(Generic[T]):
    """Queue rows with ``submit``, written by ``write(batch)`` on one task (see the module
    docstring). ``open`` on the event loop, ``close`` at the end (it writes what is queued)."""

    def __init__(
        self,
        write: Callable[[list[T]], Awaitable[object]],
        what: str,
        *,
        limit: int = WAITING_MAX,
        retry_s: float = RETRY_S,
    ) -> None:
        self._write_batch = write
        self.what = what
        """The rows in words, for the log (``alarm changes``)."""
        self.limit = limit
        self.retry_s = retry_s
        self._queue: asyncio.Queue[T | None] = asyncio.Queue()
        self._task: asyncio.Task[None] | None = None
        self.waiting: list[T] = []
        """Rows that could not be written yet, oldest first."""
        self._retry_at = 0.0
        """``time.monotonic()`` of the next try while rows wait."""
        self.lost = 0
        """Rows given up: beyond ``limit`` while waiting, or still waiting at ``close``."""

    def open(self) -> None:
        if self._task is None:
            self._task = asyncio.create_task(self._run(), name=f"writer: {self.what}")

    async def close(self) -> None:
        """Write what is queued (once more what waits), then end the task."""
        if self._task is not None:
            self._queue.put_nowait(None)
            await self._task
            self._task = None

    def submit(self, row: T) -> None:
        """Queue a row; never blocks."""
        self._queue.put_nowait(row)

    async def flush(self) -> bool:
        """Wait until every row queued so far has been tried; ``True`` if nothing waits (all
        written)."""
        await self._queue.join()
        return not self.waiting

    async def _next_batch(self) -> list[T | None]:
        """What the queue holds, waiting for the first row (at most ``retry_s`` while rows
        wait: then an empty batch, a retry)."""
        if self.waiting:
            try:
                first = await asyncio.wait_for(
                    self._queue.get(), max(0.0, self._retry_at - time.monotonic())
                )
            except TimeoutError:
                return []
        else:
            first = await self._queue.get()
        batch = [first]
        while not self._queue.empty():
            batch.append(self._queue.get_nowait())
        return batch

    async def _run(self) -> None:
        stopping = False
        while not stopping:
            batch = await self._next_batch()
            rows = [row for row in batch if row is not None]
            stopping = len(rows) != len(batch)
            try:
                await self._write(rows, stopping=stopping)
            finally:
                for _ in batch:
                    self._queue.task_done()

    async def _write(self, rows: list[T], *, stopping: bool) -> None:
        pending = self.waiting + rows
        if not pending:
            return
        if self.waiting and not stopping and time.monotonic() < self._retry_at:
            self._keep(pending)  # the disk had no room a moment ago: wait with the others
            return
        try:
            await self._write_batch(pending)
        except sqlite3.OperationalError as error:  # a full disk, an I/O error: try again later
            if stopping:
                self.lost += len(pending)
                self.waiting = []
                log.error(
                    "%s: %d lost at shutdown, not written: %s", self.what, len(pending), error
                )
                return
            if not self.waiting:
                log.error(
                    "%s cannot be written (%s): they wait in memory until they can",
                    self.what,
                    error,
                )
            self._retry_at = time.monotonic() + self.retry_s
            self._keep(pending)
            return
        except Exception:  # a batch that can never be written (a bug): it must not block the rest
            self.lost += len(pending)
            self.waiting = []
            log.exception("%s: %d not written", self.what, len(pending))
            return
        if self.waiting:
            log.warning("%s are written again (%d waited)", self.what, len(self.waiting))
        self.waiting = []

    def _keep(self, pending: list[T]) -> None:
        """``pending`` waits, the oldest given up beyond ``limit``."""
        dropped = max(0, len(pending) - self.limit)
        if dropped:
            self.lost += dropped
            log.error(
                "%s: the %d oldest of those waiting given up (%d at most wait)",
                self.what,
                dropped,
                self.limit,
            )
        self.waiting = pending[dropped:]

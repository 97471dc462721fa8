"""Layer: service. Measured cycles in the service's database (the ``cycles`` table, created by
``service.storage.migrations``), written through the store's one worker thread (``Store.call``).

A cycle is queued where it is measured (the frame path never waits on the disk) and written by
one writer task (``storage.queued_writer``: on a full disk they wait in memory until it has
room), a batch per transaction without an fsync of its own (as events are: a cycle lost to a
power cut is measured again by the next one). A range is read with its statistics
in one call: the cycles whose start lies in it, and the last, mean, minimum and maximum of its
newest N.
"""

from __future__ import annotations

import functools
import sqlite3
from dataclasses import dataclass
from typing import Final

from cobot_hmi.service.cycles.meter import Cycle
from cobot_hmi.service.storage.queued_writer import QueuedWriter
from cobot_hmi.service.storage.store import Store

_Row = tuple[object, ...]

CYCLE_COLUMNS: Final = ("id", "start", "end", "duration_s")
"""A cycle as the API answers it and the CSV lists it (times in seconds since the epoch)."""


@dataclass(frozen=True, slots=True)
class CycleStats:
    count: int
    """Cycles in the range."""
    last_s: float | None
    """The newest cycle's duration."""
    window: int
    """How many of the newest cycles the mean, min and max are of (at most the asked N)."""
    mean_s: float | None
    min_s: float | None
    max_s: float | None


@dataclass(frozen=True, slots=True)
class CycleRange:
    cycles: list[dict[str, object]]
    """Oldest first; the newest ``limit`` of the range."""
    stats: CycleStats


class CycleStore:
    """Queue cycles, write them, read ranges (see the module docstring)."""

    def __init__(self, store: Store) -> None:
        self._store = store
        self.writer: QueuedWriter[Cycle] = QueuedWriter(
            lambda cycles: store.call(functools.partial(_insert, cycles=cycles), fsync=False),
            "measured cycles",
        )

    def open(self) -> None:
        self.writer.open()

    async def close(self) -> None:
        await self.writer.close()

    def submit(self, cycle: Cycle) -> None:
        """Queue a measured cycle; never blocks."""
        self.writer.submit(cycle)

    async def flush(self) -> bool:
        """Wait until every cycle queued so far has been tried: ``True`` if all are committed,
        ``False`` if some wait in memory for room on the disk."""
        return await self.writer.flush()

    async def read_range(
        self,
        robot: str,
        *,
        since: float | None,
        until: float | None,
        limit: int,
        last_n: int,
    ) -> CycleRange:
        """The cycles of ``robot`` that started in ``[since, until)`` (the newest ``limit``,
        oldest first) and the statistics of the range's newest ``last_n``."""
        clauses = ["robot = ?"]
        params: list[object] = [robot]
        if since is not None:
            clauses.append("start >= ?")
            params.append(since)
        if until is not None:
            clauses.append("start < ?")
            params.append(until)
        where = "WHERE " + " AND ".join(clauses)

        def read(db: sqlite3.Connection) -> tuple[int, list[_Row], _Row]:
            count = int(db.execute(f"SELECT count(*) FROM cycles {where}", params).fetchone()[0])
            rows = db.execute(
                f"SELECT {', '.join(CYCLE_COLUMNS)} FROM cycles {where}"
                " ORDER BY start DESC LIMIT ?",
                (*params, limit),
            ).fetchall()
            stats = db.execute(
                "SELECT count(*), avg(duration_s), min(duration_s), max(duration_s) FROM"
                f" (SELECT duration_s FROM cycles {where} ORDER BY start DESC LIMIT ?)",
                (*params, last_n),
            ).fetchone()
            return count, rows, stats

        count, rows, (window, mean, low, high) = await self._store.call(read, fsync=False)
        cycles = [dict(zip(CYCLE_COLUMNS, row, strict=True)) for row in reversed(rows)]
        last = rows[0][3] if rows else None
        stats = CycleStats(
            count,
            float(last) if isinstance(last, int | float) else None,
            int(window),  # type: ignore[call-overload]
            _number(mean),
            _number(low),
            _number(high),
        )
        return CycleRange(cycles, stats)


def _insert(db: sqlite3.Connection, cycles: list[Cycle]) -> None:
    db.executemany(
        "INSERT INTO cycles (robot, start, end, duration_s) VALUES (?, ?, ?, ?)",
        [(c.robot, c.start, c.end, c.duration_s) for c in cycles],
    )


def _number(value: object) -> float | None:
    return float(value) if isinstance(value, int | float) else None

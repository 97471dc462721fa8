"""Layer: service. Measured cycles in the service's database (the ``cycles`` table, created by
``service.storage.migrations``), written through the store's one worker thread (``Store.call``).

A cycle is queued where it is measured (the frame path never waits on the disk) and written by
one writer task (``storage.queued_writer``: on a full disk they wait in memory until it has
room), a batch per transaction without an fsync of its own (as events are: a cycle lost to a
power cut is measured again by the next one). A range is read with its statistics
in one call: the cycles whose start lies in it, and the last, mean, minimum and maximum of its
newest N. An interrupted cycle (``meter``: a stop, a lost link, the robot out of its running
states) is kept with what interrupted it (the column ``interruption``, migration step 8) and
listed with the others, marked; the statistics leave it out unless asked to include it.
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

CYCLE_COLUMNS: Final = ("id", "start", "end", "duration_s", "interrupted", "interruption")
"""A cycle as the API answers it and the CSV lists it (times in seconds since the epoch)."""
_SELECT: Final = "id, start, end, duration_s, interruption IS NOT NULL, interruption"


@dataclass(frozen=True, slots=True)
class CycleStats:
    count: int
    """Cycles in the range the statistics are of (without the interrupted ones unless asked)."""
    interrupted: int
    """Interrupted cycles in the range."""
    last_s: float | None
    """The newest such cycle's duration."""
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
        include_interrupted: bool = False,
    ) -> CycleRange:
        """The cycles of ``robot`` that started in ``[since, until)`` (the newest ``limit``,
        oldest first, interrupted ones marked) and the statistics of the range's newest
        ``last_n`` (of whole cycles only, unless ``include_interrupted``)."""
        clauses = ["robot = ?"]
        params: list[object] = [robot]
        if since is not None:
            clauses.append("start >= ?")
            params.append(since)
        if until is not None:
            clauses.append("start < ?")
            params.append(until)
        where = "WHERE " + " AND ".join(clauses)
        counted = where if include_interrupted else f"{where} AND interruption IS NULL"

        def read(db: sqlite3.Connection) -> tuple[_Row, list[_Row], _Row, _Row | None]:
            counts = db.execute(
                f"SELECT count(*), count(interruption) FROM cycles {where}", params
            ).fetchone()
            rows = db.execute(
                f"SELECT {_SELECT} FROM cycles {where} ORDER BY start DESC LIMIT ?",
                (*params, limit),
            ).fetchall()
            stats = db.execute(
                "SELECT count(*), avg(duration_s), min(duration_s), max(duration_s) FROM"
                f" (SELECT duration_s FROM cycles {counted} ORDER BY start DESC LIMIT ?)",
                (*params, last_n),
            ).fetchone()
            newest = db.execute(
                f"SELECT duration_s FROM cycles {counted} ORDER BY start DESC LIMIT 1", params
            ).fetchone()
            return counts, rows, stats, newest

        counts, rows, stats_row, newest = await self._store.call(read, fsync=False)
        (total, interrupted), (window, mean, low, high) = counts, stats_row
        cycles = [_row(row) for row in reversed(rows)]
        last = newest[0] if newest else None
        count = int(total) - (0 if include_interrupted else int(interrupted))  # type: ignore[call-overload]
        stats = CycleStats(
            count,
            int(interrupted),  # type: ignore[call-overload]
            float(last) if isinstance(last, int | float) else None,
            int(window),  # type: ignore[call-overload]
            _number(mean),
            _number(low),
            _number(high),
        )
        return CycleRange(cycles, stats)


def _row(row: _Row) -> dict[str, object]:
    cycle = dict(zip(CYCLE_COLUMNS, row, strict=True))
    cycle["interrupted"] = bool(cycle["interrupted"])
    return cycle


def _insert(db: sqlite3.Connection, cycles: list[Cycle]) -> None:
    db.executemany(
        "INSERT INTO cycles (robot, start, end, duration_s, interruption) VALUES (?, ?, ?, ?, ?)",
        [(c.robot, c.start, c.end, c.duration_s, c.interruption) for c in cycles],
    )


def _number(value: object) -> float | None:
    return float(value) if isinstance(value, int | float) else None

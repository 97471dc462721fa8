"""Layer: service. Alarms in the service's database: each alarm's current record (so a restart
keeps the active and unacknowledged ones, their acknowledgements and shelving) and the history
of every transition.

Two tables beside the audit and the events (``service.storage.store``; created by
``service.storage.migrations``), written through the store's one worker thread (``Store.call``). A
transition is queued where it happens (the frame path never waits on the disk) and written in
order by one writer task (``storage.queued_writer``), a batch per transaction; an operator's
acknowledgement or shelving waits for its batch (``flush``) before the answer, committed with
fsync. On a full disk the transitions wait in memory and are written, in order, once it has
room.
"""

from __future__ import annotations

import functools
import sqlite3
from collections.abc import AsyncIterator
from dataclasses import dataclass
from typing import Final

import orjson

from cobot_hmi.service.alarms import definitions as d
from cobot_hmi.service.labels import robot_state_words, unit_of
from cobot_hmi.service.storage.queued_writer import QueuedWriter
from cobot_hmi.service.storage.search import Search
from cobot_hmi.service.storage.store import Page, Store

HISTORY_TEXT_COLUMNS: Final = (
    "robot",
    "alarm_id",
    "key",
    "name",
    "transition",
    "state",
    "message",
    "label",
    "tag",
    "user",
    "comment",
    "suppressed_by",
)
"""What a text search of the alarm history looks in."""
HISTORY_BATCH_ROWS: Final = 1000
"""Rows a streamed CSV of the alarm history reads at a time."""
HISTORY_COLUMNS: Final = (
    "id",
    "time",
    "robot",
    "alarm_id",
    "key",
    "name",
    "priority",
    "transition",
    "state",
    "shelved",
    "message",
    "value",
    "label",
    "tag",
    "user",
    "comment",
    "suppressed_by",
)
HISTORY_CSV_COLUMNS: Final = (
    *HISTORY_COLUMNS[: HISTORY_COLUMNS.index("value") + 1],
    "value_words",
    *HISTORY_COLUMNS[HISTORY_COLUMNS.index("value") + 1 :],
)
"""A history CSV's columns: the stored ones and the value in words beside the value."""
_STATE_KEYS: Final = frozenset({d.EMERGENCY_STOP, d.PROTECTIVE_STOP, d.SAFE_OFF})
_UNITS: Final = {
    d.MOTOR_TEMPERATURE: unit_of("joint_motor_temperature.0"),
    d.PACKET_LOSS: "gaps/min",
}


def value_words(key: str, value: object) -> str | None:
    """A history row's watched value as a person reads it: a state alarm's robot state by its
    label ("Emergency stop", never "0"), a temperature with its unit ("81.2 °C"), a rate with
    its ("12 gaps/min"), a bit "on"/"off"; ``None`` when the row has no value. Read from the
    key and the value alone, so rows written before the words existed read the same."""
    if value is None:
        return None
    if isinstance(value, bool):
        return "on" if value else "off"
    if key in _STATE_KEYS and isinstance(value, int | float) and float(value).is_integer():
        return robot_state_words(int(value))
    if isinstance(value, int | float):
        unit = _UNITS.get(key.partition(".")[0], "")
        return f"{value:g} {unit}".rstrip()
    return str(value)


@dataclass(frozen=True, slots=True)
class AlarmChange:
    """One transition of one alarm, as it is stored."""

    time: float
    robot: str
    alarm_id: str
    key: str
    name: str
    priority: str
    transition: str
    state: str
    shelved: bool
    message: str | None
    value: float | bool | None
    label: str | None
    tag: str | None
    user: str | None
    comment: str | None
    record: dict[str, object]
    """The alarm's whole record after the change (``state.AlarmStatus.to_json``)."""
    suppressed_by: str | None = None
    """The cause's alarm id when the alarm is suppressed by design (state ``suppressed``)."""


class AlarmStore:
    """The alarm tables of one ``Store``: ``open`` after the store opened, ``close`` before it
    closes."""

    def __init__(self, store: Store) -> None:
        self._store = store
        self.writer: QueuedWriter[AlarmChange] = QueuedWriter(
            lambda changes: store.call(functools.partial(_write_sync, changes=changes)),
            "alarm changes",
        )

    @property
    def write_errors(self) -> int:
        """Changes lost: not written and given up (``QueuedWriter.lost``)."""
        return self.writer.lost

    async def open(self) -> None:
        self.writer.open()

    async def close(self) -> None:
        await self.writer.close()

    async def load(self, robot: str) -> dict[str, dict[str, object]]:
        """The persisted records of one robot's alarms, by key."""

        def read(db: sqlite3.Connection) -> list[tuple[str, str]]:
            rows: list[tuple[str, str]] = db.execute(
                "SELECT key, data FROM alarm_state WHERE robot = ?", (robot,)
            ).fetchall()
            return rows

        out: dict[str, dict[str, object]] = {}
        for key, data in await self._store.call(read, fsync=False):
            try:
                record = orjson.loads(data)
            except orjson.JSONDecodeError:
                continue  # a damaged row: the alarm starts normal
            if isinstance(record, dict):
                out[key] = record
        return out

    def submit(self, change: AlarmChange) -> None:
        """Queue a transition; never blocks (the frame path calls it)."""
        self.writer.submit(change)

    async def flush(self) -> bool:
        """Wait until every transition queued so far has been tried: ``True`` if all are
        committed, ``False`` if some wait in memory for room on the disk."""
        return await self.writer.flush()

    async def history_page(
        self,
        limit: int,
        offset: int,
        *,
        robot: str | None = None,
        priority: str | None = None,
        since: float | None = None,
        until: float | None = None,
        q: str | None = None,
    ) -> Page:
        """Transitions, newest first, optionally of one robot, one priority, a time range."""
        where, params = _history_filter(robot, priority, since, until, q)

        def read(db: sqlite3.Connection) -> tuple[int, list[tuple[object, ...]]]:
            total = db.execute(f"SELECT count(*) FROM alarm_history {where}", params).fetchone()
            rows = db.execute(
                f"SELECT {', '.join(HISTORY_COLUMNS)} FROM alarm_history {where}"
                " ORDER BY id DESC LIMIT ? OFFSET ?",
                (*params, limit, offset),
            ).fetchall()
            return int(total[0]), rows

        total, rows = await self._store.call(read, fsync=False)
        return Page([_history_item(row) for row in rows], total)

    async def history_count(
        self,
        *,
        robot: str | None = None,
        priority: str | None = None,
        since: float | None = None,
        until: float | None = None,
        q: str | None = None,
    ) -> tuple[int, int]:
        """``(total, newest id)`` of the transitions a filter selects (``history_all`` reads
        up to that id: one snapshot, whatever comes meanwhile)."""
        where, params = _history_filter(robot, priority, since, until, q)

        def read(db: sqlite3.Connection) -> tuple[int, int]:
            total, newest = db.execute(
                f"SELECT count(*), max(id) FROM alarm_history {where}", params
            ).fetchone()
            return int(total), int(newest or 0)

        result: tuple[int, int] = await self._store.call(read, fsync=False)
        return result

    async def history_all(
        self,
        newest_id: int,
        *,
        robot: str | None = None,
        priority: str | None = None,
        since: float | None = None,
        until: float | None = None,
        q: str | None = None,
        batch_rows: int = HISTORY_BATCH_ROWS,
    ) -> AsyncIterator[list[dict[str, object]]]:
        """Every transition a filter selects with an id up to ``newest_id``, newest first, in
        batches of ``batch_rows`` (each a keyset query: ``id < last``, so memory holds one
        batch and the database is not held between batches)."""
        where, params = _history_filter(robot, priority, since, until, q)
        joiner = " AND " if where else "WHERE "
        below = newest_id + 1
        while True:

            def read(db: sqlite3.Connection, below: int = below) -> list[tuple[object, ...]]:
                rows: list[tuple[object, ...]] = db.execute(
                    f"SELECT {', '.join(HISTORY_COLUMNS)} FROM alarm_history {where}"
                    f"{joiner}id < ? ORDER BY id DESC LIMIT ?",
                    (*params, below, batch_rows),
                ).fetchall()
                return rows

            rows = await self._store.call(read, fsync=False)
            if not rows:
                return
            yield [_history_item(row) for row in rows]
            if len(rows) < batch_rows:
                return
            last = rows[-1][0]
            assert isinstance(last, int)
            below = last


def _history_filter(
    robot: str | None,
    priority: str | None,
    since: float | None,
    until: float | None,
    q: str | None = None,
) -> tuple[str, list[object]]:
    search = Search(since, until, q)
    return search.where({"robot": robot, "priority": priority}, HISTORY_TEXT_COLUMNS)


def _history_item(row: tuple[object, ...]) -> dict[str, object]:
    item = dict(zip(HISTORY_COLUMNS, row, strict=True))
    item["shelved"] = bool(item["shelved"])
    text = item["value"]
    item["value"] = orjson.loads(text) if isinstance(text, str) else None
    item["value_words"] = value_words(str(item["key"]), item["value"])
    return item


def _write_sync(db: sqlite3.Connection, changes: list[AlarmChange]) -> None:
    db.executemany(
        "INSERT INTO alarm_history (time, robot, alarm_id, key, name, priority, transition,"
        " state, shelved, message, value, label, tag, user, comment, suppressed_by)"
        " VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
        [
            (
                c.time,
                c.robot,
                c.alarm_id,
                c.key,
                c.name,
                c.priority,
                c.transition,
                c.state,
                int(c.shelved),
                c.message,
                None if c.value is None else orjson.dumps(c.value).decode(),
                c.label,
                c.tag,
                c.user,
                c.comment,
                c.suppressed_by,
            )
            for c in changes
        ],
    )
    db.executemany(
        "INSERT INTO alarm_state (id, robot, key, data, time) VALUES (?, ?, ?, ?, ?)"
        " ON CONFLICT (id) DO UPDATE SET data = excluded.data, time = excluded.time",
        [(c.alarm_id, c.robot, c.key, orjson.dumps(c.record).decode(), c.time) for c in changes],
    )

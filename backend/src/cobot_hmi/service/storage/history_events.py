"""Layer: service. The event log of one robot over a time range, for a history export
(the MCAP ``/ROBOT/events`` channel), read from the store's SQLite file by a connection of its
own, read-only: the service's store keeps writing (WAL lets both run), and ``cobot-hmi export``
reads a state directory without a service. Imports nothing of the project.

Each event is the log's flat form (``docs/api.md``, Events): its kind's own fields plus
``kind``, ``time``, ``robot`` and ``id``, oldest first. An export reads them a batch at a time
(``iter_events``), so its memory does not grow with the range's events.
"""

from __future__ import annotations

import sqlite3
from collections.abc import Iterator
from pathlib import Path
from typing import Final

import orjson

_KEYS = frozenset({"id", "time", "robot", "kind"})
EVENT_BATCH_ROWS: Final = 1000
"""Events an export reads at a time."""


def iter_events(
    database: Path, robot: str, from_s: float, to_s: float, *, batch_rows: int = EVENT_BATCH_ROWS
) -> Iterator[dict[str, object]]:
    """Every event of ``robot`` with ``from_s <= time < to_s``, oldest first, read
    ``batch_rows`` at a time, each batch by a connection of its own (a streamed export's
    iterator may be advanced from different threads), after the last ``(time, id)`` read."""
    after: tuple[float, int] | None = None
    while True:
        rows = _read(database, robot, from_s, to_s, limit=batch_rows, after=after)
        yield from (_flat(row) for row in rows)
        if len(rows) < batch_rows:
            return
        last = rows[-1]
        after = (float(last[1]), int(last[0]))


def events_between(
    database: Path,
    robot: str,
    from_s: float,
    to_s: float,
    *,
    limit: int = 1_000_000,
    kinds: set[str] | None = None,
) -> list[dict[str, object]]:
    """Events of ``robot`` (of ``kinds``, default all) with ``from_s <= time < to_s``, oldest
    first, at most ``limit``; none when there is no database."""
    rows = _read(database, robot, from_s, to_s, limit=limit, kinds=kinds)
    return [_flat(row) for row in rows]


_Row = tuple[int, float, str, str, str]


def _read(
    database: Path,
    robot: str,
    from_s: float,
    to_s: float,
    *,
    limit: int,
    kinds: set[str] | None = None,
    after: tuple[float, int] | None = None,
) -> list[_Row]:
    if not database.exists():
        return []
    try:
        db = sqlite3.connect(f"{database.resolve().as_uri()}?mode=ro", uri=True, timeout=5.0)
    except sqlite3.Error:
        return []
    try:
        kind_list = sorted(kinds) if kinds else []
        only = f" AND kind IN ({', '.join('?' * len(kind_list))})" if kind_list else ""
        params: list[object] = [robot, from_s, to_s, *kind_list]
        if after is not None:
            only += " AND (time > ? OR (time = ? AND id > ?))"
            params += [after[0], after[0], after[1]]
        rows: list[_Row] = db.execute(
            "SELECT id, time, robot, kind, data FROM events"
            f" WHERE robot = ? AND time >= ? AND time < ?{only} ORDER BY time, id LIMIT ?",
            (*params, limit),
        ).fetchall()
    except sqlite3.Error:  # no events table yet
        return []
    finally:
        db.close()
    return rows


def _flat(row: _Row) -> dict[str, object]:
    row_id, time_s, robot_name, kind, data = row
    try:
        fields = orjson.loads(data)
    except orjson.JSONDecodeError:
        fields = {"data": data}
    own = fields if isinstance(fields, dict) else {"data": fields}
    return {
        **{k: v for k, v in own.items() if k not in _KEYS},
        "id": row_id,
        "time": time_s,
        "robot": robot_name,
        "kind": kind,
    }

"""Layer: service. The event log of one robot over a time range, for a history export
(the MCAP ``/ROBOT/events`` channel), read from the store's SQLite file by a connection of its
own, read-only: the service's store keeps writing (WAL lets both run), and ``cobot-hmi export``
reads a state directory without a service. Imports nothing of the project.

Each event is the log's flat form (``docs/api.md``, Events): its kind's own fields plus
``kind``, ``time``, ``robot`` and ``id``, oldest first.
"""

from __future__ import annotations

import sqlite3
from pathlib import Path

import orjson

_KEYS = frozenset({"id", "time", "robot", "kind"})


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
    if not database.exists():
        return []
    try:
        db = sqlite3.connect(f"{database.resolve().as_uri()}?mode=ro", uri=True, timeout=5.0)
    except sqlite3.Error:
        return []
    try:
        kind_list = sorted(kinds) if kinds else []
        only = f" AND kind IN ({', '.join('?' * len(kind_list))})" if kind_list else ""
        rows = db.execute(
            "SELECT id, time, robot, kind, data FROM events"
            f" WHERE robot = ? AND time >= ? AND time < ?{only} ORDER BY time, id LIMIT ?",
            (robot, from_s, to_s, *kind_list, limit),
        ).fetchall()
    except sqlite3.Error:  # no events table yet
        return []
    finally:
        db.close()
    out: list[dict[str, object]] = []
    for row_id, time_s, robot_name, kind, data in rows:
        try:
            fields = orjson.loads(data)
        except orjson.JSONDecodeError:
            fields = {"data": data}
        own = fields if isinstance(fields, dict) else {"data": fields}
        out.append(
            {
                **{k: v for k, v in own.items() if k not in _KEYS},
                "id": row_id,
                "time": time_s,
                "robot": robot_name,
                "kind": kind,
            }
        )
    return out

"""Layer: service. The schema of the service's database (``hmi.db``) as one ordered list of
migrations, its version kept in SQLite's ``PRAGMA user_version``.

``migrate`` runs when the store opens (``Store.open``): the steps after the database's version,
in order, in ONE transaction that also sets the new version; a failure leaves the database as it
was. A database of a newer version than ``SCHEMA_VERSION`` (written by a newer cobot-hmi) is
refused with ``SchemaTooNewError``, untouched. The audit trail, the event log, the alarm tables
and the tag names (``store``, ``alarms.persistence``, ``tags``) only read and write their rows;
this module alone creates and changes tables.

Databases before versions (the code up to 58f13a2) have ``user_version`` 0, as a new file has.
Steps 1–3 are that history (the first release; robot and origin columns; summaries, tag names
and alarms) written to be idempotent: they create what is missing and add only the columns a
table lacks, so every shape those versions left, a new file included, ends at version 3 with
the same schema. A step after 3 runs exactly once (its database's version says it has not run),
so it is plain DDL or data changes; append it to ``MIGRATIONS`` with the next version, never
edit a released one. Imports nothing of the project.
"""

from __future__ import annotations

import sqlite3
from dataclasses import dataclass
from pathlib import Path
from typing import Final


@dataclass(frozen=True, slots=True)
class AddColumn:
    """``ALTER TABLE table ADD COLUMN column declaration`` unless the column is there."""

    table: str
    column: str
    declaration: str

    def apply(self, db: sqlite3.Connection) -> None:
        present = {row[1] for row in db.execute(f"PRAGMA table_info({self.table})")}
        if self.column not in present:
            db.execute(f"ALTER TABLE {self.table} ADD COLUMN {self.column} {self.declaration}")


Step = str | AddColumn
"""One SQL statement, or a column added when missing."""


@dataclass(frozen=True, slots=True)
class Migration:
    version: int
    """The database's ``user_version`` once this step ran."""
    what: str
    steps: tuple[Step, ...]


MIGRATIONS: Final = (
    Migration(
        1,
        "the audit trail and the event log",
        (
            """CREATE TABLE IF NOT EXISTS audit (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    time REAL NOT NULL,
    user TEXT,
    client TEXT,
    action TEXT NOT NULL,
    fields TEXT NOT NULL,
    before TEXT,
    requested TEXT,
    outcome TEXT NOT NULL,
    reason TEXT
)""",
            """CREATE TABLE IF NOT EXISTS events (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    time REAL NOT NULL,
    kind TEXT NOT NULL,
    data TEXT NOT NULL
)""",
            "CREATE INDEX IF NOT EXISTS events_kind ON events (kind, id)",
        ),
    ),
    Migration(
        2,
        "the robot and the request's origin of each audit row and event",
        (
            AddColumn("audit", "robot", "TEXT"),
            AddColumn("audit", "origin", "TEXT"),
            AddColumn("events", "robot", "TEXT"),
            "CREATE INDEX IF NOT EXISTS events_robot ON events (robot, id)",
            "CREATE INDEX IF NOT EXISTS audit_robot ON audit (robot, id)",
        ),
    ),
    Migration(
        3,
        "audit summaries and tag names; alarm records and history; the tag names",
        (
            AddColumn("audit", "summary", "TEXT"),
            AddColumn("audit", "tags", "TEXT"),
            """CREATE TABLE IF NOT EXISTS alarm_state (
    id TEXT PRIMARY KEY,
    robot TEXT NOT NULL,
    key TEXT NOT NULL,
    data TEXT NOT NULL,
    time REAL NOT NULL
)""",
            """CREATE TABLE IF NOT EXISTS alarm_history (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    time REAL NOT NULL,
    robot TEXT NOT NULL,
    alarm_id TEXT NOT NULL,
    key TEXT NOT NULL,
    name TEXT NOT NULL,
    priority TEXT NOT NULL,
    transition TEXT NOT NULL,
    state TEXT NOT NULL,
    shelved INTEGER NOT NULL,
    message TEXT,
    value TEXT,
    label TEXT,
    tag TEXT,
    user TEXT,
    comment TEXT
)""",
            "CREATE INDEX IF NOT EXISTS alarm_history_robot ON alarm_history (robot, id)",
            """CREATE TABLE IF NOT EXISTS tags (
    robot TEXT NOT NULL,
    key TEXT NOT NULL,
    name TEXT NOT NULL,
    PRIMARY KEY (robot, key)
)""",
        ),
    ),
    Migration(
        4,
        "alarm history: the cause of an alarm suppressed by design",
        ("ALTER TABLE alarm_history ADD COLUMN suppressed_by TEXT",),
    ),
    Migration(
        5,
        "I/O checkouts (loop checks) with their points; output presets",
        (
            """CREATE TABLE checkouts (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    robot TEXT NOT NULL,
    started_at REAL NOT NULL,
    started_by TEXT NOT NULL,
    closed_at REAL,
    closed_by TEXT,
    identity TEXT
)""",
            "CREATE INDEX checkouts_robot ON checkouts (robot, id)",
            """CREATE TABLE checkout_points (
    checkout_id INTEGER NOT NULL REFERENCES checkouts (id),
    key TEXT NOT NULL,
    result TEXT NOT NULL,
    data TEXT NOT NULL,
    PRIMARY KEY (checkout_id, key)
)""",
            """CREATE TABLE presets (
    robot TEXT NOT NULL,
    name TEXT NOT NULL,
    items TEXT NOT NULL,
    created_at REAL NOT NULL,
    created_by TEXT NOT NULL,
    PRIMARY KEY (robot, name)
)""",
        ),
    ),
    Migration(
        6,
        "cycle times: every measured cycle of every robot (start, end, duration)",
        (
            """CREATE TABLE cycles (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    robot TEXT NOT NULL,
    start REAL NOT NULL,
    end REAL NOT NULL,
    duration_s REAL NOT NULL
)""",
            "CREATE INDEX cycles_robot_start ON cycles (robot, start)",
        ),
    ),
    Migration(
        7,
        "the audit trail's hash chain (storage/audit_chain.py): each final row's seal, the "
        "chain's head, and the last row written before it (sealed when the store opens)",
        (
            "ALTER TABLE audit ADD COLUMN seal_seq INTEGER",
            "ALTER TABLE audit ADD COLUMN seal_hash TEXT",
            "CREATE UNIQUE INDEX audit_seal ON audit (seal_seq)",
            """CREATE TABLE audit_chain (
    id INTEGER PRIMARY KEY CHECK (id = 1),
    seal_seq INTEGER NOT NULL,
    seal_hash TEXT NOT NULL,
    row_id INTEGER,
    legacy_last_id INTEGER NOT NULL,
    legacy_sealed_at REAL
)""",
            "INSERT INTO audit_chain (id, seal_seq, seal_hash, legacy_last_id)"
            " SELECT 1, 0, '" + "0" * 64 + "', coalesce(max(id), 0) FROM audit",
        ),
    ),
    Migration(
        8,
        "cycle times: what interrupted a cycle (a stop, a lost link, the robot out of its "
        "running states); NULL for a whole cycle, as every cycle measured before",
        ("ALTER TABLE cycles ADD COLUMN interruption TEXT",),
    ),
    Migration(
        9,
        "robot health (service.health): each robot's engine state (a versioned JSON document: "
        "life used, knocks, baselines), its baselines with who set them and why, and the "
        "periodic snapshots of its figures that the trends and the weekly report read",
        (
            """CREATE TABLE health_state (
    robot TEXT PRIMARY KEY,
    saved_at REAL NOT NULL,
    document TEXT NOT NULL
)""",
            """CREATE TABLE health_baselines (
    robot TEXT NOT NULL,
    id INTEGER NOT NULL,
    created_at REAL NOT NULL,
    created_by TEXT NOT NULL,
    reason TEXT NOT NULL,
    arm TEXT NOT NULL,
    layout_version INTEGER NOT NULL,
    target_cycles INTEGER,
    cycles INTEGER,
    learned_from REAL,
    learned_to REAL,
    record TEXT NOT NULL,
    PRIMARY KEY (robot, id)
)""",
            """CREATE TABLE health_snapshots (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    robot TEXT NOT NULL,
    time REAL NOT NULL,
    baseline_id INTEGER,
    verdict TEXT NOT NULL,
    cycles INTEGER NOT NULL,
    joints TEXT NOT NULL
)""",
            "CREATE INDEX health_snapshots_robot_time ON health_snapshots (robot, time)",
        ),
    ),
)
SCHEMA_VERSION: Final = MIGRATIONS[-1].version
"""The version this code writes and reads."""


class SchemaTooNewError(RuntimeError):
    """The database was written by a newer cobot-hmi: its schema is unknown here."""

    def __init__(self, path: Path | str, version: int) -> None:
        super().__init__(
            f"{path}: the database has schema version {version}, newer than this cobot-hmi "
            f"knows ({SCHEMA_VERSION}); it was written by a newer cobot-hmi. Run that version, "
            "or point --database (or --state-dir) at another file; this one is left untouched"
        )
        self.path = path
        self.version = version


def schema_version(db: sqlite3.Connection) -> int:
    version: int = db.execute("PRAGMA user_version").fetchone()[0]
    return version


def check_version(db: sqlite3.Connection, path: Path | str) -> int:
    """The database's schema version; ``SchemaTooNewError`` when newer than the code's."""
    version = schema_version(db)
    if version > SCHEMA_VERSION:
        raise SchemaTooNewError(path, version)
    return version


def migrate(db: sqlite3.Connection, path: Path | str) -> tuple[int, int]:
    """Bring the database to ``SCHEMA_VERSION`` in one transaction; ``(from, to)`` versions.

    ``db`` is not in a transaction. ``BEGIN IMMEDIATE`` takes the write lock before the
    version is read again, so two processes opening one file migrate it once."""
    if check_version(db, path) == SCHEMA_VERSION:
        return SCHEMA_VERSION, SCHEMA_VERSION
    db.execute("BEGIN IMMEDIATE")
    try:
        before = check_version(db, path)
        for migration in MIGRATIONS:
            if migration.version <= before:
                continue
            for step in migration.steps:
                if isinstance(step, AddColumn):
                    step.apply(db)
                else:
                    db.execute(step)
        # PRAGMA takes no parameters; SCHEMA_VERSION is this module's own integer.
        db.execute(f"PRAGMA user_version = {SCHEMA_VERSION:d}")
        db.commit()
    except BaseException:
        db.rollback()
        raise
    return before, SCHEMA_VERSION

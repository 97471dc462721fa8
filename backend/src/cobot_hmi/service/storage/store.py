"""Layer: service. The audit trail and the event log, in SQLite (WAL), durable across a crash.

One connection, used only from one worker thread, so the event loop never waits on the disk.
Every commit reaches the operating system before the call returns, so it survives ``kill -9``
of the service. Commits that precede an answer (an audit row's outcome, a refusal, a control
change) are also fsync'd (``synchronous=FULL``): they survive power loss too. A write's
``pending`` row, committed just before the robot is commanded, is written without its own
fsync (``synchronous=NORMAL``); the outcome's fsync a few milliseconds later covers it too (the
WAL is one sequential file), which keeps one disk flush instead of two on every write's path.
Events (robot state, flags, connection) arrive in bursts from the broadcast loop; they are
queued and written a batch per transaction, without fsync of their own (``queued_writer``: on
a full disk they wait in memory until it has room). The tables (these two, the alarms' and the
tag names') are created and upgraded by ``migrations`` when the store opens; imports nothing
else of the project but ``errors``, ``audit_backlog``, ``audit_chain`` and ``queued_writer``.

A full disk (or any failed write): ``add_audit`` raises ``AuditUnavailableError`` (503), so a
caller that must audit before it acts does not act. What already happened (a write's outcome
after the robot confirmed it, a control change, a refusal) is kept in memory and written as
soon as the disk has room (``audit_backlog``: before the next audit write, and every
``AUDIT_RETRY_S``); ``finish_audit`` and ``keep_audit`` say whether it is in yet. A ``pending``
row a crash left (the outcome never written) is marked ``interrupted`` when the store opens.

Every audit row is sealed into a hash chain in the transaction that makes it final
(``audit_chain``: an insert with its outcome, a pending row's outcome, ``interrupted``); the
chain's head is read every ``CHAIN_HEAD_INTERVAL_S`` for ``/metrics`` and logged when it moved.
"""

from __future__ import annotations

import asyncio
import contextlib
import csv
import dataclasses
import functools
import io
import logging
import os
import sqlite3
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any, Final, TypeVar

import orjson

from cobot_hmi.service.errors import AuditUnavailableError
from cobot_hmi.service.plant_time import PLANT_ZONE
from cobot_hmi.service.storage import audit_chain, migrations
from cobot_hmi.service.storage.audit_backlog import AuditBacklog, Deferred
from cobot_hmi.service.storage.queued_writer import QueuedWriter
from cobot_hmi.service.storage.search import NO_SEARCH, Search

_T = TypeVar("_T")
log = logging.getLogger(__name__)

AUDIT_COLUMNS: Final = (*audit_chain.SEALED, "seal_seq", "seal_hash")
"""The audit page's and its CSV's columns: the row as sealed, then its seal."""
_AUDIT_JSON: Final = frozenset({"fields", "before", "requested", "tags"})
EVENT_COLUMNS: Final = ("id", "time", "robot", "kind", "text", "data")
"""The CSV columns of the event log (``text``: the event in words; ``data``: the kind's own
fields as JSON text)."""
_EVENT_KEYS: Final = frozenset({"id", "time", "robot", "kind"})
_Event = tuple[float, str, str | None, dict[str, object]]
"""An event as it waits to be written: time (s since the epoch), kind, robot, its own fields."""
AUDIT_TEXT_COLUMNS: Final = (
    "robot",
    "user",
    "client",
    "origin",
    "action",
    "fields",
    "outcome",
    "reason",
    "summary",
    "tags",
)
"""What a text search of the audit trail looks in."""
EVENT_TEXT_COLUMNS: Final = (
    "robot",
    "kind",
    "COALESCE(CASE WHEN json_valid(data) THEN json_extract(data, '$.text') END, data)",
)
"""What a text search of the event log looks in: the event's words (its ``text``, which the
stream, the CSV and the panel show), not its fields' keys and values, so that every row a search
returns says what was searched; an event logged before events had a text: its fields."""
MAX_PAGE: Final = 100_000
"""Largest ``limit`` of one page (a CSV export takes everything in one)."""
CHAIN_HEAD_INTERVAL_S: Final = 60.0
"""How often the audit chain's head is read for ``/metrics`` and logged (when it moved)."""
AUDIT_RETRY_S: Final = 1.0
"""How often audit rows waiting for room (a full disk) are tried again."""
AUDIT_BACKLOG_MAX: Final = 10_000
"""Refusals' rows kept while the audit trail cannot be written (what happened is kept
whatever this says: ``audit_backlog``)."""
INTERRUPTED: Final = "interrupted"
"""The outcome a ``pending`` row gets when the store opens: the service stopped before it."""
INTERRUPTED_REASON: Final = (
    "the service stopped before the outcome was written (a crash, or a full disk at its stop: "
    "see its log); whether the robot applied it is not known"
)


@dataclass(frozen=True, slots=True)
class AuditEntry:
    """One write attempt or control change, as it is stored."""

    user: str | None
    client: str | None
    action: str
    fields: Sequence[str]
    before: object
    requested: object
    outcome: str
    reason: str | None
    time: float = 0.0
    robot: str | None = None
    """The robot's name (``None``: not about one robot)."""
    origin: str | None = None
    """Which door the request came through (``PATCH /api/v1/robots/{name}/command``, MQTT…)."""
    summary: str | None = None
    """What was asked, in words with the spec's labels ("AO 1 type = voltage, AO 1 = 5 V")."""
    tags: Mapping[str, str] | None = None
    """Tag names of the touched points at the time (``{"controlbox_do.2": "gripper close"}``)."""


@dataclass(frozen=True, slots=True)
class Page:
    items: list[dict[str, object]]
    total: int


class Store:
    """The database at ``path``. ``open`` before use, ``close`` at the end."""

    def __init__(self, path: Path, *, chain_head_interval_s: float = CHAIN_HEAD_INTERVAL_S) -> None:
        self.path = path
        self.chain_head_interval_s = chain_head_interval_s
        self.chain_head: audit_chain.ChainHead | None = None
        """The audit chain's head as last read (``chain_head_interval_s``)."""
        self._chain_task: asyncio.Task[None] | None = None
        self._executor: ThreadPoolExecutor | None = None
        self._connection: sqlite3.Connection | None = None
        self.event_writer: QueuedWriter[_Event] = QueuedWriter(
            lambda events: self._run(self._add_events_sync, events), "events"
        )
        self.audit_backlog = AuditBacklog(AUDIT_BACKLOG_MAX)
        """Audit rows and outcomes waiting for room (used on the worker thread only)."""
        self._backlog_waiting = asyncio.Event()
        self._retrier: asyncio.Task[None] | None = None
        self._loop: asyncio.AbstractEventLoop | None = None

    async def open(self) -> None:
        """Open (or create) the database and bring its schema to this code's version
        (``migrations``); ``SchemaTooNewError`` for a database of a newer cobot-hmi."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="store")
        try:
            await self._run(self._open_sync)
        except BaseException:
            self._executor.shutdown(wait=True)
            self._executor = None
            raise
        self.chain_head = await self._run(lambda: audit_chain.head(self._db()))
        self.event_writer.open()
        self._loop = asyncio.get_running_loop()
        self._retrier = asyncio.create_task(self._retry_backlog(), name="store-audit-backlog")
        self._chain_task = asyncio.create_task(self._watch_chain_head(), name="store-chain-head")

    def _open_sync(self) -> None:
        # The audit trail names users and client addresses: readable by the service's own user
        # only. Created (or narrowed) to 0600 before SQLite opens it; SQLite gives the -wal and
        # -shm files the database file's mode.
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o600)
        try:
            os.fchmod(fd, 0o600)
        finally:
            os.close(fd)
        for suffix in ("-wal", "-shm"):
            with contextlib.suppress(FileNotFoundError):
                os.chmod(f"{self.path}{suffix}", 0o600)
        connection = sqlite3.connect(self.path, check_same_thread=False)
        try:
            # A newer cobot-hmi's database is refused before anything is written to it.
            migrations.check_version(connection, self.path)
            connection.execute("PRAGMA journal_mode=WAL")
            connection.execute("PRAGMA synchronous=FULL")
            migrations.migrate(connection, self.path)
            with connection:  # the outcome of an attempt a crash interrupted, sealed
                interrupted = [
                    row_id
                    for (row_id,) in connection.execute(
                        "SELECT id FROM audit WHERE outcome = 'pending' AND seal_seq IS NULL"
                    )
                ]
                connection.execute(
                    "UPDATE audit SET outcome = ?, reason = ? WHERE outcome = 'pending'"
                    " AND seal_seq IS NULL",
                    (INTERRUPTED, INTERRUPTED_REASON),
                )
                legacy = audit_chain.seal_at_open(connection, interrupted, time.time())
            if legacy:
                log.warning(
                    "%s: %d audit rows from before the hash chain sealed now (their content "
                    "before this moment is not proven)",
                    self.path,
                    legacy,
                )
        except BaseException:
            connection.close()
            raise
        self._connection = connection

    async def close(self) -> None:
        if self._chain_task is not None:
            self._chain_task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._chain_task
            self._chain_task = None
        if self._retrier is not None:
            self._retrier.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._retrier
            self._retrier = None
            if not await self._run(self._flush_backlog_sync):
                await self._run(self.audit_backlog.give_up)
        await self.event_writer.close()
        if self._executor is not None:
            if self._connection is not None:
                await self._run(self._connection.close)
                self._connection = None
            self._executor.shutdown(wait=True)
            self._executor = None

    async def _run(self, function: Callable[..., _T], *args: Any) -> _T:
        assert self._executor is not None, "Store.open() first"
        return await asyncio.get_running_loop().run_in_executor(self._executor, function, *args)

    def _db(self) -> sqlite3.Connection:
        assert self._connection is not None
        return self._connection

    @contextlib.contextmanager
    def _synchronous(self, level: str) -> Iterator[sqlite3.Connection]:
        """A transaction committed with ``PRAGMA synchronous=<level>`` (FULL: fsync'd)."""
        db = self._db()
        db.execute(f"PRAGMA synchronous={level}")
        with db:
            yield db

    async def call(self, function: Callable[[sqlite3.Connection], _T], *, fsync: bool = True) -> _T:
        """Run ``function(connection)`` in one transaction on the store's worker thread (the
        tables of other modules: alarms, tag names), committed durably unless ``fsync=False``."""
        return await self._run(self._call_sync, function, fsync)

    def _call_sync(self, function: Callable[[sqlite3.Connection], _T], fsync: bool) -> _T:
        with self._synchronous("FULL" if fsync else "NORMAL") as db:
            return function(db)

    # ----------------------------------------------------------------- audit

    async def add_audit(self, entry: AuditEntry, *, fsync: bool = True) -> int:
        """Insert and commit one audit row (fsync'd unless told otherwise); its id.
        ``AuditUnavailableError`` when it cannot be written (nothing kept: the caller must not
        act on it)."""
        return await self._run(self._add_audit_sync, entry, fsync)

    def _add_audit_sync(self, entry: AuditEntry, fsync: bool) -> int:
        try:
            with self._synchronous("FULL" if fsync else "NORMAL") as db:
                self.audit_backlog.write(db)  # what waits goes first, in the same commit
                row_id = _insert_audit(db, entry)
        except sqlite3.Error as error:
            raise AuditUnavailableError(audit_failure(error)) from None
        self.audit_backlog.done()
        return row_id

    async def keep_audit(self, entry: AuditEntry, *, happened: bool = False) -> bool:
        """Insert a row about something already decided (a refusal, a control change),
        committed durably; ``False``: the disk has no room now and the row waits in memory
        (``audit_backlog``; a refusal only while there is room, what ``happened`` always)."""
        timed = dataclasses.replace(entry, time=entry.time or time.time())
        what = (
            f"{timed.action} by {timed.user or 'nobody'} ({timed.robot or '-'}, "
            f"{timed.origin or '-'}): {timed.outcome}, {timed.reason or ''} "
            f"{orjson.dumps(timed.requested, default=repr).decode()}"
        )
        insert = functools.partial(_insert_audit, entry=timed)
        return await self._run(self._write_or_keep, Deferred(insert, what, happened))

    async def finish_audit(self, row_id: int, outcome: str, reason: str | None) -> bool:
        """Set the outcome of a row written as ``pending``, committed durably; ``False``: the
        disk has no room now and the outcome waits in memory until it has (``audit_backlog``)."""
        update = functools.partial(_finish_audit, row_id=row_id, outcome=outcome, reason=reason)
        what = f"audit row {row_id}: outcome {outcome} ({reason or ''})"
        return await self._run(self._write_or_keep, Deferred(update, what, happened=True))

    def _write_or_keep(self, deferred: Deferred) -> bool:
        try:
            with self._synchronous("FULL") as db:
                self.audit_backlog.write(db)
                deferred.write(db)
        except sqlite3.Error as error:
            self.audit_backlog.keep(deferred, _cause(error))
            if self._loop is not None:
                self._loop.call_soon_threadsafe(self._backlog_waiting.set)
            return False
        self.audit_backlog.done()
        return True

    def _flush_backlog_sync(self) -> bool:
        """Write what waits; whether nothing waits now."""
        if not self.audit_backlog.items:
            return True
        try:
            with self._synchronous("FULL") as db:
                self.audit_backlog.write(db)
        except sqlite3.Error:
            return False
        self.audit_backlog.done()
        return True

    async def _retry_backlog(self) -> None:
        while True:
            await self._backlog_waiting.wait()
            await asyncio.sleep(AUDIT_RETRY_S)
            if await self._run(self._flush_backlog_sync):
                self._backlog_waiting.clear()
                if self.audit_backlog.items:  # kept meanwhile, after the flush
                    self._backlog_waiting.set()

    async def read_chain_head(self) -> audit_chain.ChainHead:
        """The audit chain's head now (also kept in ``chain_head``)."""
        self.chain_head = await self._run(lambda: audit_chain.head(self._db()))
        return self.chain_head

    async def _watch_chain_head(self) -> None:
        logged: audit_chain.ChainHead | None = None
        while True:
            try:
                current = await self.read_chain_head()
            except sqlite3.Error as error:
                log.error("the audit chain's head cannot be read: %s", error)
            else:
                if current != logged:  # a warning: what the service's stderr carries by default
                    log.warning("audit chain head: %s", current.describe())
                    logged = current
            await asyncio.sleep(self.chain_head_interval_s)

    async def audit_page(
        self, limit: int, offset: int, *, robot: str | None = None, search: Search = NO_SEARCH
    ) -> Page:
        """Audit rows, newest first, optionally of one robot, a time range, a text."""
        return await self._run(_audit_page, self._db(), limit, offset, robot, search)

    # ----------------------------------------------------------------- events

    def submit_event(
        self, time_s: float, kind: str, data: dict[str, object], robot: str | None = None
    ) -> None:
        """Queue an event for the log; never blocks, written within one batch."""
        self.event_writer.submit((time_s, kind, robot, data))

    def log_event(self, event: Mapping[str, object]) -> None:
        """Queue an event as the stream carries it (``kind``, ``time``, ``robot`` and the kind's
        own fields, ``docs/api.md``)."""
        time_s = event.get("time")
        robot = event.get("robot")
        self.submit_event(
            float(time_s) if isinstance(time_s, int | float) else time.time(),
            str(event.get("kind", "")) or "unknown",
            {k: v for k, v in event.items() if k not in _EVENT_KEYS},
            robot if isinstance(robot, str) else None,
        )

    @property
    def event_write_errors(self) -> int:
        """Events lost: not written and given up (``QueuedWriter.lost``)."""
        return self.event_writer.lost

    def _add_events_sync(self, events: list[_Event]) -> None:
        rows = [(t, robot, kind, orjson.dumps(data).decode()) for t, kind, robot, data in events]
        with self._synchronous("NORMAL") as db:
            db.executemany("INSERT INTO events (time, robot, kind, data) VALUES (?, ?, ?, ?)", rows)

    async def flush_events(self) -> bool:
        """Wait until every event submitted so far has been tried (tests, shutdown): ``True``
        if all are committed, ``False`` if some wait for room on the disk."""
        return await self.event_writer.flush()

    async def events_page(
        self,
        kind: str | None,
        limit: int,
        offset: int,
        *,
        robot: str | None = None,
        search: Search = NO_SEARCH,
    ) -> Page:
        """Events, newest first, optionally of one kind, one robot, a time range, a text. Each
        item is the event as the stream carries it plus its ``id`` (``event_csv_rows`` gathers
        the kind's fields)."""
        page = functools.partial(_events_page, robot=robot, search=search)
        return await self._run(page, self._db(), kind, limit, offset)


def _audit_page(
    db: sqlite3.Connection, limit: int, offset: int, robot: str | None, search: Search
) -> Page:
    """Audit rows, newest first (on the store's worker thread)."""
    where, params = search.where({"robot": robot}, AUDIT_TEXT_COLUMNS)
    total = db.execute(f"SELECT count(*) FROM audit {where}", params).fetchone()[0]
    rows = db.execute(
        f"SELECT {', '.join(AUDIT_COLUMNS)} FROM audit {where} ORDER BY id DESC LIMIT ? OFFSET ?",
        (*params, limit, offset),
    ).fetchall()
    items = []
    for row in rows:
        item = dict(zip(AUDIT_COLUMNS, row, strict=True))
        for name in _AUDIT_JSON:
            text = item[name]
            item[name] = orjson.loads(text) if isinstance(text, str) else None
        items.append(item)
    return Page(items, int(total))


def _events_page(
    db: sqlite3.Connection,
    kind: str | None,
    limit: int,
    offset: int,
    *,
    robot: str | None,
    search: Search,
) -> Page:
    """Events, newest first (on the store's worker thread)."""
    where, params = search.where({"kind": kind, "robot": robot}, EVENT_TEXT_COLUMNS)
    total = db.execute(f"SELECT count(*) FROM events {where}", params).fetchone()[0]
    rows = db.execute(
        f"SELECT id, time, robot, kind, data FROM events {where} ORDER BY id DESC LIMIT ? OFFSET ?",
        (*params, limit, offset),
    ).fetchall()
    items = []
    for row_id, time_s, robot_name, kind_name, data in rows:
        fields = orjson.loads(data)
        own = fields if isinstance(fields, dict) else {"data": fields}
        items.append(
            {
                **{k: v for k, v in own.items() if k not in _EVENT_KEYS},
                "id": row_id,
                "time": time_s,
                "robot": robot_name,
                "kind": kind_name,
            }
        )
    return Page(items, int(total))


def _insert_audit(db: sqlite3.Connection, entry: AuditEntry) -> int:
    cursor = db.execute(
        "INSERT INTO audit (time, robot, user, client, origin, action, fields, before,"
        " requested, outcome, reason, summary, tags)"
        " VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
        (
            entry.time or time.time(),
            entry.robot,
            entry.user,
            entry.client,
            entry.origin,
            entry.action,
            orjson.dumps(list(entry.fields)).decode(),
            orjson.dumps(entry.before).decode(),
            orjson.dumps(entry.requested).decode(),
            entry.outcome,
            entry.reason,
            entry.summary,
            None if entry.tags is None else orjson.dumps(dict(entry.tags)).decode(),
        ),
    )
    row_id = cursor.lastrowid
    assert row_id is not None
    if entry.outcome != audit_chain.PENDING:  # final: sealed now (a pending row with its outcome)
        audit_chain.seal(db, row_id)
    return row_id


def _finish_audit(db: sqlite3.Connection, row_id: int, outcome: str, reason: str | None) -> None:
    if not audit_chain.finish(db, row_id, outcome, reason):
        log.error("audit row %d is sealed already: outcome %s not written", row_id, outcome)


def _cause(error: sqlite3.Error) -> str:
    """Why SQLite could not write, in words (``disk full (database or disk is full)``)."""
    if getattr(error, "sqlite_errorcode", None) == sqlite3.SQLITE_FULL:
        return f"disk full ({error})"
    return str(error) or type(error).__name__


def audit_failure(error: sqlite3.Error) -> str:
    """The refusal's reason when the audit trail cannot be written."""
    return f"the audit trail cannot be written: {_cause(error)}"


def event_csv_rows(items: Sequence[dict[str, object]]) -> list[dict[str, object]]:
    """Events page items as CSV rows: the kind's own fields gathered in ``data``."""
    return [
        {
            **{k: item.get(k) for k in _EVENT_KEYS},
            "text": item.get("text"),
            "data": {k: v for k, v in item.items() if k not in _EVENT_KEYS and k != "text"},
        }
        for item in items
    ]


def iso8601(time_s: float) -> str:
    """Seconds since the epoch as ISO 8601 in the plant's time zone (the ``time_zone``
    setting, ``plant_time``) with its UTC offset (``2026-11-24T07:05:12.345678+01:00``,
    24 h, always six decimals: every row the same width): what a spreadsheet and a person both
    read, in the zone the pages show."""
    return datetime.fromtimestamp(time_s, PLANT_ZONE.zone).isoformat(timespec="microseconds")


def to_csv(
    items: Sequence[dict[str, object]],
    columns: Sequence[str],
    *,
    time_columns: Sequence[str] = ("time",),
    header: bool = True,
) -> str:
    """A page as CSV with a header row (unless not ``header``: a streamed export's later
    parts); nested values as JSON text; ``time_columns`` (seconds since the epoch) as ISO 8601
    with offset."""
    out = io.StringIO()
    writer = csv.writer(out)
    if header:
        writer.writerow(columns)
    for item in items:
        row = []
        for name in columns:
            value = item.get(name)
            if name in time_columns and isinstance(value, int | float):
                row.append(iso8601(value))
            elif isinstance(value, dict | list):
                row.append(orjson.dumps(value).decode())
            else:
                row.append("" if value is None else str(value))
        writer.writerow(row)
    return out.getvalue()

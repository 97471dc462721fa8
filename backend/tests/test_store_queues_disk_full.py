"""The queued rows of the database (events, alarm transitions, measured cycles:
``storage.queued_writer``) on a real full disk: the service's database on a small tmpfs,
filled with a file and freed again. Nothing is lost while the disk is full: the rows wait in
memory and are written, in the order they came, once it has room; only beyond the limit are
the oldest given up, and counted. A row that can never be written is given up alone."""

from __future__ import annotations

import contextlib
import sqlite3
from collections.abc import AsyncIterator
from pathlib import Path

import pytest

from cobot_hmi.service.alarms.persistence import AlarmChange, AlarmStore
from cobot_hmi.service.cycles.meter import Cycle
from cobot_hmi.service.cycles.store import CycleStore
from cobot_hmi.service.storage.store import Store
from service_support import eventually
from tmpfs_support import fill, free, small_tmpfs

pytestmark = pytest.mark.timeout(120)

ROWS = 300
"""Each kind's rows submitted while the disk is full: more than its WAL holds unwritten."""
PADDING = "x" * 1000
"""Each event's and alarm message's size: the WAL has to grow to take them."""


@contextlib.asynccontextmanager
async def stores(database: Path) -> AsyncIterator[tuple[Store, AlarmStore, CycleStore]]:
    store = Store(database)
    await store.open()
    alarms, cycles = AlarmStore(store), CycleStore(store)
    await alarms.open()
    cycles.open()
    try:
        yield store, alarms, cycles
    finally:
        await cycles.close()
        await alarms.close()
        await store.close()


def change(number: int) -> AlarmChange:
    return AlarmChange(
        time=1_000.0 + number,
        robot="r1",
        alarm_id="r1:packet_loss",
        key="packet_loss",
        name="Packet loss",
        priority="medium",
        transition="raised" if number % 2 == 0 else "cleared",
        state="unack_active" if number % 2 == 0 else "unack_normal",
        shelved=False,
        message=f"{number} {PADDING}",
        value=float(number),
        label=None,
        tag=None,
        user=None,
        comment=None,
        record={"number": number},
    )


def read(database: Path, sql: str) -> list[tuple[object, ...]]:
    with contextlib.closing(sqlite3.connect(f"{database.as_uri()}?mode=ro", uri=True)) as db:
        return db.execute(sql).fetchall()


async def test_rows_wait_for_room_and_are_written_in_order(tmp_path: Path) -> None:
    with small_tmpfs(tmp_path / "disk", 4) as disk:
        database = disk / "hmi.db"
        async with stores(database) as (store, alarms, cycles):
            store.submit_event(1.0, "note", {"n": -1})
            assert await store.flush_events()
            filler = fill(disk)
            try:
                for n in range(ROWS):
                    store.submit_event(2.0 + n, "note", {"n": n, "padding": PADDING})
                    alarms.submit(change(n))
                    cycles.submit(Cycle("r1", 10.0 + n, 11.0 + n))
                assert not await store.flush_events()
                assert not await alarms.flush()
                assert not await cycles.flush()
                for writer in (store.event_writer, alarms.writer, cycles.writer):
                    assert writer.waiting and writer.lost == 0, writer.what
            finally:
                free(filler)
            # Retried by themselves (every RETRY_S), with nothing new submitted.
            await eventually(
                lambda: (
                    not (store.event_writer.waiting or alarms.writer.waiting)
                    and not cycles.writer.waiting
                ),
                timeout_s=30,
            )
            assert (store.event_write_errors, alarms.write_errors, cycles.writer.lost) == (0, 0, 0)
        events = read(database, "SELECT json_extract(data, '$.n') FROM events ORDER BY id")
        assert [n for (n,) in events] == list(range(-1, ROWS))
        messages = read(database, "SELECT message FROM alarm_history ORDER BY id")
        assert [str(m).split()[0] for (m,) in messages] == [str(n) for n in range(ROWS)]
        # The alarm's record is the last change's, as it would be without the full disk.
        (record,) = read(database, "SELECT json_extract(data, '$.number') FROM alarm_state")
        assert record == (ROWS - 1,)
        starts = read(database, "SELECT start FROM cycles ORDER BY id")
        assert [s for (s,) in starts] == [10.0 + n for n in range(ROWS)]


async def test_beyond_the_limit_the_oldest_are_given_up_and_counted(tmp_path: Path) -> None:
    with small_tmpfs(tmp_path / "disk", 4) as disk:
        database = disk / "hmi.db"
        async with stores(database) as (store, _, _):
            store.event_writer.limit = 50
            filler = fill(disk)
            try:
                for n in range(ROWS):
                    store.submit_event(1.0 + n, "note", {"n": n, "padding": PADDING})
                assert not await store.flush_events()
                assert len(store.event_writer.waiting) == 50
                assert store.event_write_errors == ROWS - 50
            finally:
                free(filler)
            assert await eventually_flushed(store)
        events = read(database, "SELECT json_extract(data, '$.n') FROM events ORDER BY id")
        assert [n for (n,) in events] == list(range(ROWS - 50, ROWS))


async def test_what_still_waits_at_close_is_counted_as_lost(tmp_path: Path) -> None:
    with small_tmpfs(tmp_path / "disk", 4) as disk:
        database = disk / "hmi.db"
        async with stores(database) as (_, alarms, _):
            filler = fill(disk)
            try:
                for n in range(ROWS):
                    alarms.submit(change(n))
                assert not await alarms.flush()
                await alarms.close()
                assert alarms.write_errors == ROWS and not alarms.writer.waiting
            finally:
                free(filler)


async def test_a_row_that_can_never_be_written_does_not_hold_back_the_rest(
    tmp_path: Path,
) -> None:
    database = tmp_path / "hmi.db"
    async with stores(database) as (store, _, _):
        store.submit_event(1.0, "note", {"n": 0})
        assert await store.flush_events()
        store.submit_event(2.0, "note", {"n": {1, 2}})  # a set: no JSON for it, ever
        assert await store.flush_events()
        assert store.event_write_errors == 1
        store.submit_event(3.0, "note", {"n": 2})
        assert await store.flush_events()
    events = read(database, "SELECT json_extract(data, '$.n') FROM events ORDER BY id")
    assert [n for (n,) in events] == [0, 2]


async def eventually_flushed(store: Store) -> bool:
    await eventually(lambda: not store.event_writer.waiting, timeout_s=30)
    return await store.flush_events()

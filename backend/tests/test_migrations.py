"""The database's schema migrations (``service/storage/migrations.py``) on databases the older
code wrote.

The fixtures in ``legacy/`` are databases as the code of 58f13a2 (the last commit without schema
versions: every table, rows of a real session), 5606929 and 3dfff02 (older shapes, before the
columns ``ALTER`` added) wrote them, as ``iterdump`` SQL; ``legacy/make_legacy.py`` made them
by running that code. Each is rebuilt into a real file, then opened by today's code.
"""

from __future__ import annotations

import contextlib
import sqlite3
from pathlib import Path

import pytest

from cobot_hmi.composition import build_service
from cobot_hmi.emulator.target import Target
from cobot_hmi.service.alarms.persistence import AlarmChange, AlarmStore
from cobot_hmi.service.storage import migrations
from cobot_hmi.service.storage.migrations import SCHEMA_VERSION, Migration, SchemaTooNewError
from cobot_hmi.service.storage.store import AuditEntry, Store
from cobot_hmi.service.storage.tags import TagBook
from service_support import ADMIN, OPERATOR, running_service, service_settings

pytestmark = pytest.mark.timeout(120)

LEGACY = Path(__file__).parent / "legacy"
ROBOT = "m1013"
"""The robot of the 58f13a2 database."""
TABLES = ("audit", "events", "alarm_state", "alarm_history", "tags")


def legacy_database(commit: str, directory: Path) -> Path:
    """``legacy/hmi-<commit>.sql`` rebuilt as a database file (``user_version`` 0, as then)."""
    path = directory / f"hmi-{commit}.db"
    with contextlib.closing(sqlite3.connect(path)) as db:
        db.executescript((LEGACY / f"hmi-{commit}.sql").read_text())
        assert migrations.schema_version(db) == 0
    return path


def schema(path: Path) -> set[tuple[str, str, str | None]]:
    """Every table and index as SQLite keeps its statement."""
    with contextlib.closing(sqlite3.connect(path)) as db:
        rows = db.execute(
            "SELECT type, name, sql FROM sqlite_master WHERE name NOT LIKE 'sqlite_%'"
        ).fetchall()
    return {(kind, name, sql) for kind, name, sql in rows}


def rows(path: Path) -> dict[str, list[tuple[object, ...]]]:
    with contextlib.closing(sqlite3.connect(path)) as db:
        present = {r[0] for r in db.execute("SELECT name FROM sqlite_master WHERE type='table'")}
        return {
            table: db.execute(f"SELECT * FROM {table} ORDER BY rowid").fetchall()
            for table in TABLES
            if table in present
        }


def version_of(path: Path) -> int:
    with contextlib.closing(sqlite3.connect(path)) as db:
        return migrations.schema_version(db)


def files(directory: Path) -> dict[str, bytes]:
    return {path.name: path.read_bytes() for path in sorted(directory.iterdir())}


async def open_store(path: Path) -> None:
    store = Store(path)
    await store.open()
    await store.close()


async def test_a_new_database_has_the_schema_58f13a2_made(tmp_path: Path) -> None:
    """The steps reproduce, statement for statement, what the code before versions created
    (steps 1-3), and the steps after it change a new database and an upgraded one alike."""
    new = tmp_path / "new.db"
    await open_store(new)
    assert version_of(new) == SCHEMA_VERSION
    legacy = legacy_database("58f13a2", tmp_path)
    made = schema(legacy)
    await open_store(legacy)
    assert schema(new) == schema(legacy)
    # Since then, alarm_history has the cause of an alarm suppressed by design (step 4), the
    # audit rows their seals (step 7).
    changed = {entry for entry in made if entry not in schema(new)}
    assert {name for _, name, _ in changed} == {"alarm_history", "audit"}


async def test_a_database_of_58f13a2_keeps_every_row(tmp_path: Path) -> None:
    path = legacy_database("58f13a2", tmp_path)
    before = rows(path)
    assert set(before) == set(TABLES) and all(before.values())  # rows in every table
    assert len(before["audit"]) == 7 and len(before["alarm_history"]) == 7
    # What the steps since add: the alarm history's suppressed_by column, empty on old rows.
    before["alarm_history"] = [(*row, None) for row in before["alarm_history"]]
    new_schema = tmp_path / "new.db"
    await open_store(new_schema)
    store = Store(path)
    await store.open()
    alarm_store = AlarmStore(store)
    await alarm_store.open()
    try:
        assert version_of(path) == SCHEMA_VERSION
        now = rows(path)
        now["audit"] = [row[:-2] for row in now["audit"]]  # its seals: test_audit_chain.py
        assert now == before
        assert schema(path) == schema(new_schema)
        # The store's own readers, on the old rows.
        audit = await store.audit_page(100, 0)
        assert audit.total == 7
        write = next(item for item in audit.items if item["outcome"] == "confirmed")
        assert write["summary"] == "DO 3 (gripper close) = on"
        assert write["tags"] == {"controlbox_do.2": "gripper close"}
        assert write["requested"] == {"controlbox_do.2": True}
        events = await store.events_page(None, 1000, 0, robot=ROBOT)
        assert events.total == len(before["events"])
        assert sum(e["kind"] == "alarm" for e in events.items) == 7  # one per transition
        records = await alarm_store.load(ROBOT)
        assert records["emergency_stop"]["acknowledged_by"] == "olivia"
        assert records["protective_stop"]["shelved_by"] == "olivia"
        history = await alarm_store.history_page(100, 0, robot=ROBOT)
        assert [item["transition"] for item in reversed(history.items)] == [
            "activated",
            "acknowledged",
            "cleared",
            "activated",
            "cleared",
            "activated",
            "shelved",
        ]
        tags = TagBook(ROBOT)
        await tags.load(store)
        assert tags.names == {
            "controlbox_do.2": "gripper close",
            "bit_input_registers.40": "part ready",
        }
        # And new rows go in beside them.
        row = await store.add_audit(
            AuditEntry("bob", None, "control.take", [], None, None, "granted", None, robot=ROBOT)
        )
        assert row == 8
        await tags.replace(store, {"controlbox_do.3": "lamp"})
        alarm_store.submit(_change(ROBOT))
        await alarm_store.flush()
        assert (await alarm_store.history_page(1, 0)).total == 8
    finally:
        await alarm_store.close()
        await store.close()
    await open_store(path)  # at its version: nothing to do, nothing changed
    after = rows(path)
    assert [row[:-2] for row in after["audit"][:7]] == before["audit"]
    assert len(after["audit"]) == 8
    assert after["alarm_history"][:7] == before["alarm_history"]


def _change(robot: str) -> AlarmChange:
    return AlarmChange(
        time=1.0,
        robot=robot,
        alarm_id=f"{robot}:emergency_stop",
        key="emergency_stop",
        name="Emergency stop",
        priority="critical",
        transition="activated",
        state="active_unacknowledged",
        shelved=False,
        message=None,
        value=0,
        label=None,
        tag=None,
        user=None,
        comment=None,
        record={"state": "active_unacknowledged"},
    )


@pytest.mark.parametrize(
    ("commit", "robot_column"),
    [("3dfff02", False), ("5606929", True)],
    ids=["first-release", "robot-columns"],
)
async def test_an_older_shape_is_upgraded_to_the_same_schema(
    tmp_path: Path, commit: str, robot_column: bool
) -> None:
    path = legacy_database(commit, tmp_path)
    before = rows(path)
    assert set(before) == {"audit", "events"}
    assert len(before["audit"]) == 3 and len(before["events"]) == 2
    store = Store(path)
    await store.open()
    try:
        audit = await store.audit_page(10, 0)
        assert audit.total == 3
        oldest = audit.items[-1]
        assert oldest["action"] == "control.take" and oldest["user"] == "alice"
        assert oldest["robot"] == ("left" if robot_column else None)
        assert oldest["summary"] is None and oldest["tags"] is None
        write = audit.items[-2]
        assert write["outcome"] == "confirmed" and write["requested"] == [True]
        events = await store.events_page(None, 10, 0)
        assert [e["kind"] for e in events.items] == ["robot_state", "flag"]
        assert events.items[1]["value"] is True
        tags = TagBook("left")
        await tags.replace(store, {"controlbox_do.2": "gripper close"})
    finally:
        await store.close()
    assert version_of(path) == SCHEMA_VERSION
    new = tmp_path / "new.db"
    await open_store(new)
    assert schema(path) == schema(new)
    upgraded = rows(path)
    width = len(before["audit"][0])
    assert [row[:width] for row in upgraded["audit"]] == before["audit"]
    assert upgraded["tags"] == [("left", "controlbox_do.2", "gripper close")]


async def test_a_newer_database_is_refused_untouched(tmp_path: Path) -> None:
    path = tmp_path / "newer.db"
    with contextlib.closing(sqlite3.connect(path)) as db:
        db.execute("CREATE TABLE audit (id INTEGER PRIMARY KEY, what_a_newer_version_has TEXT)")
        db.execute(f"PRAGMA user_version = {SCHEMA_VERSION + 1}")
        db.commit()
    before = files(tmp_path)
    store = Store(path)
    with pytest.raises(SchemaTooNewError) as refused:
        await store.open()
    message = str(refused.value)
    assert str(path) in message
    assert f"schema version {SCHEMA_VERSION + 1}" in message
    assert f"knows ({SCHEMA_VERSION})" in message
    assert files(tmp_path) == before  # no -wal, no -shm, not a byte changed
    await store.close()  # nothing left open: a no-op


async def test_the_service_refuses_to_start_on_a_newer_database(
    target: Target, robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    path = tmp_path / "hmi.db"
    with contextlib.closing(sqlite3.connect(path)) as db:
        db.execute(f"PRAGMA user_version = {SCHEMA_VERSION + 7}")
    settings = service_settings(robot_host, target.tcp_port, plc_host, tmp_path, database=path)
    service = build_service(settings)
    with pytest.raises(SchemaTooNewError, match=f"schema version {SCHEMA_VERSION + 7}"):
        await service.start()
    assert version_of(path) == SCHEMA_VERSION + 7


async def test_a_failing_step_leaves_the_database_as_it_was(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """All pending steps are one transaction: a step that fails undoes the ones before it."""
    path = legacy_database("3dfff02", tmp_path)
    before, old_schema = rows(path), schema(path)
    broken = Migration(
        SCHEMA_VERSION + 1,
        "a step that fails half-way",
        (migrations.AddColumn("audit", "extra", "TEXT"), "INSERT INTO no_such_table VALUES (1)"),
    )
    monkeypatch.setattr(migrations, "MIGRATIONS", (*migrations.MIGRATIONS, broken))
    monkeypatch.setattr(migrations, "SCHEMA_VERSION", broken.version)
    with pytest.raises(sqlite3.OperationalError, match="no_such_table"):
        await open_store(path)
    assert version_of(path) == 0
    assert schema(path) == old_schema
    assert rows(path) == before


async def test_the_service_works_on_a_database_of_58f13a2(
    target: Target, robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    path = legacy_database("58f13a2", tmp_path)
    settings = service_settings(
        robot_host, target.tcp_port, plc_host, tmp_path, robot_name=ROBOT, database=path
    )
    async with running_service(settings) as hmi:
        async with hmi.client(await hmi.login(OPERATOR)) as operator:
            audit = (await operator.get("/api/v1/audit", params={"limit": 100})).json()
            assert audit["total"] >= 7  # the old rows, and the logins since
            actions = [item["action"] for item in audit["items"]]
            assert {"tags.update", "write", "alarm.ack", "alarm.shelve"} <= set(actions)
            events = (await operator.get("/api/v1/events", params={"kind": "alarm"})).json()
            assert events["total"] >= 7
            history = (await operator.get("/api/v1/alarms/history")).json()
            assert history["total"] >= 7
            alarm = (await operator.get(f"/api/v1/alarms/{ROBOT}:emergency_stop")).json()
            assert alarm["acknowledged_by"] == "olivia"  # the persisted record, restored
            tags = (await operator.get(f"/api/v1/robots/{ROBOT}/tags")).json()
            assert tags["tags"]["controlbox_do.2"] == "gripper close"
            taken = await operator.post(f"/api/v1/robots/{ROBOT}/control/take")
            assert taken.status_code == 200, taken.text
            wrote = await operator.patch(
                f"/api/v1/robots/{ROBOT}/command", json={"controlbox_do": {"2": True}}
            )
            assert wrote.status_code == 200, wrote.text
        async with hmi.client(await hmi.login(ADMIN)) as admin:
            newest = (await admin.get("/api/v1/audit", params={"limit": 1})).json()["items"][0]
            assert newest["action"] == "write" and newest["summary"] == "DO 3 (gripper close) = on"
            assert newest["id"] > 7
    assert version_of(path) == SCHEMA_VERSION

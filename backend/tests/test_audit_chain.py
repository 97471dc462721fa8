"""The audit trail's hash chain (``service/storage/audit_chain.py``) and ``cobot-hmi audit
verify``: real database files written by the store, tampered with by hand through sqlite3 as
someone with the file would, then verified by the command as a user runs it."""

from __future__ import annotations

import asyncio
import contextlib
import csv
import io
import logging
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

from cobot_hmi.cli import main
from cobot_hmi.service.storage import audit_chain
from cobot_hmi.service.storage.store import AuditEntry, Store
from service_support import OPERATOR, Running, hmi_fixture
from test_migrations import legacy_database
from waiting import eventually

pytestmark = pytest.mark.timeout(120)


def entry(action: str, outcome: str, user: str = "ada", reason: str | None = None) -> AuditEntry:
    return AuditEntry(user, "127.0.0.1", action, ["controlbox_do.2"], None, {"x": 1}, outcome,
                      reason, robot="left")  # fmt: skip


async def write_rows(state_dir: Path) -> Path:
    """Five rows as the service writes them: final at once, pending then finished, a pending
    row's outcome after later rows (the chain's order is the order rows became final)."""
    store = Store(state_dir / "hmi.db")
    await store.open()
    try:
        await store.keep_audit(entry("login", "ok"))  # row 1, seal 1
        write = await store.add_audit(entry("write", "pending"), fsync=False)  # row 2
        await store.keep_audit(entry("control.take", "refused", reason="held"))  # row 3, seal 2
        assert await store.finish_audit(write, "confirmed", None)  # row 2, seal 3
        await store.add_audit(entry("tags.update", "ok"))  # row 4, seal 4
        await store.keep_audit(entry("logout", "ok"))  # row 5, seal 5
        head = await store.read_chain_head()
        assert (head.seq, head.row_id) == (5, 5)
    finally:
        await store.close()
    return state_dir / "hmi.db"


def tamper(path: Path, *statements: str) -> None:
    with contextlib.closing(sqlite3.connect(path)) as db:
        for statement in statements:
            db.execute(statement)
        db.commit()


def verify(state_dir: Path, capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    code = main(["audit", "verify", "--state-dir", str(state_dir)])
    captured = capsys.readouterr()
    return code, captured.out + captured.err


async def test_an_intact_trail_verifies_with_its_row_count(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = await write_rows(tmp_path)
    with contextlib.closing(sqlite3.connect(path)) as db:
        seals = db.execute("SELECT id, seal_seq FROM audit ORDER BY id").fetchall()
    assert seals == [(1, 1), (2, 3), (3, 2), (4, 4), (5, 5)]
    code, out = verify(tmp_path, capsys)
    assert code == 0, out
    assert "audit trail intact: 5 rows, 5 sealed" in out
    assert "head seal #5, row 5" in out
    assert "before the hash chain" not in out


def test_the_command_runs_as_installed(tmp_path: Path) -> None:
    """The real command line, in its own process: exit 1 and the row named."""
    path = asyncio.run(write_rows(tmp_path))
    tamper(path, "UPDATE audit SET user = 'mallory' WHERE id = 4")
    done = subprocess.run(
        [sys.executable, "-m", "cobot_hmi.cli", "audit", "verify", "--state-dir", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert done.returncode == 1, done.stdout + done.stderr
    assert "audit trail TAMPERED: row 4 changed" in done.stdout


@pytest.mark.parametrize(
    ("statement", "first"),
    [
        ("UPDATE audit SET outcome = 'confirmed' WHERE id = 3", "row 3 changed"),
        ("UPDATE audit SET reason = 'fine' WHERE id = 2", "row 2 changed"),  # a finished outcome
        ("UPDATE audit SET time = time + 1 WHERE id = 1", "row 1 changed"),
        ("UPDATE audit SET requested = '{\"x\": 1}' WHERE id = 5", "row 5 changed"),  # a space
        ("UPDATE audit SET seal_hash = '" + "f" * 64 + "' WHERE id = 4", "row 4 changed"),
    ],
    ids=["outcome", "finished-reason", "time", "json-text", "seal"],
)
async def test_an_edited_row_is_named(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], statement: str, first: str
) -> None:
    path = await write_rows(tmp_path)
    tamper(path, statement)
    code, out = verify(tmp_path, capsys)
    assert code == 1, out
    assert f"audit trail TAMPERED: {first}" in out


async def test_deleted_rows_are_found(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = await write_rows(tmp_path)
    tamper(path, "DELETE FROM audit WHERE id = 3")  # seal 2
    code, out = verify(tmp_path, capsys)
    assert code == 1, out
    assert "TAMPERED: 1 row(s) deleted: seal #2 missing, between row 1 and row 2" in out


async def test_the_newest_rows_deleted_are_found(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = await write_rows(tmp_path)
    tamper(path, "DELETE FROM audit WHERE id >= 4")  # seals 4 and 5
    code, out = verify(tmp_path, capsys)
    assert code == 1, out
    assert "TAMPERED: 2 newest row(s) deleted: seal #4–#5 missing after row 2" in out


async def test_inserted_rows_are_found(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = await write_rows(tmp_path)
    columns = "time, robot, user, client, action, fields, requested, outcome"
    values = "1.0, 'left', 'ada', '127.0.0.1', 'write', '[]', '{}', 'confirmed'"
    tamper(path, f"INSERT INTO audit ({columns}) VALUES ({values})")  # no seal: row 6
    code, out = verify(tmp_path, capsys)
    assert code == 1, out
    assert "TAMPERED: row 6 inserted: it carries no seal (outcome 'confirmed'" in out
    # One that brings a seal of its own, beyond the head (the head record left alone).
    tamper(
        path,
        "DELETE FROM audit WHERE id = 6",
        f"INSERT INTO audit ({columns}, seal_seq, seal_hash) VALUES ({values}, 6, '{'a' * 64}')",
    )
    code, out = verify(tmp_path, capsys)
    assert code == 1, out
    assert "TAMPERED: row 7 inserted: its seal #6 is beyond the chain's head #5" in out


async def test_a_row_appended_with_a_valid_seal_shows_against_the_head(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Someone who knows the algorithm seals a row of their own after the last one; the head
    record in audit_chain still names the service's last seal."""
    path = await write_rows(tmp_path)
    with contextlib.closing(sqlite3.connect(path)) as db:
        last = db.execute("SELECT seal_hash FROM audit WHERE seal_seq = 5").fetchone()[0]
        cursor = db.execute(
            "INSERT INTO audit (time, action, fields, outcome) VALUES (2.0, 'write', '[]', 'ok')"
        )
        content = db.execute(
            f"SELECT {', '.join(audit_chain.SEALED)} FROM audit WHERE id = ?", (cursor.lastrowid,)
        ).fetchone()
        forged = audit_chain.seal_hash(last, 6, content)
        db.execute("UPDATE audit SET seal_seq = 6, seal_hash = ? WHERE id = 6", (forged,))
        db.commit()
    code, out = verify(tmp_path, capsys)
    assert code == 1, out
    assert "row 6 inserted: its seal #6 is beyond the chain's head #5" in out


async def test_a_pending_row_is_not_tampering_and_is_sealed_at_the_next_start(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = await write_rows(tmp_path)
    store = Store(path)
    await store.open()
    await store.add_audit(entry("write", "pending"), fsync=False)  # row 6, then a "crash"
    code, out = verify(tmp_path, capsys)  # read only, beside the open store
    assert code == 0, out
    assert "intact: 6 rows, 5 sealed" in out
    assert "1 pending row(s) not sealed yet" in out and ": 6" in out
    await store.close()
    reopened = Store(path)
    await reopened.open()  # marks it interrupted, and seals it
    assert reopened.chain_head is not None and reopened.chain_head.row_id == 6
    await reopened.close()
    code, out = verify(tmp_path, capsys)
    assert code == 0, out
    assert "intact: 6 rows, 6 sealed" in out and "pending row" not in out
    # A sealed row's outcome is not written again.
    again = Store(path)
    await again.open()
    assert await again.finish_audit(6, "confirmed", None)  # committed: nothing to write
    await again.close()
    with contextlib.closing(sqlite3.connect(path)) as db:
        assert db.execute("SELECT outcome FROM audit WHERE id = 6").fetchone() == ("interrupted",)


async def test_a_database_from_before_the_chain_is_sealed_at_migration(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = legacy_database("58f13a2", tmp_path)
    unmigrated = main(["audit", "verify", "--database", str(path), "--state-dir", str(tmp_path)])
    out = capsys.readouterr()
    assert unmigrated == 2
    assert "no hash chain yet" in out.err
    store = Store(path)
    await store.open()  # migrated: the 7 old rows sealed
    await store.keep_audit(entry("login", "ok"))  # row 8, sealed as the service writes
    await store.close()
    code, out_text = verify_database(path, tmp_path, capsys)
    assert code == 0, out_text
    assert "intact: 8 rows, 8 sealed" in out_text
    assert "rows up to id 7 were written before the hash chain and sealed when the database " in (
        out_text
    )
    with contextlib.closing(sqlite3.connect(path)) as db:
        seals = db.execute("SELECT id, seal_seq FROM audit ORDER BY id").fetchall()
    assert seals == [(n, n) for n in range(1, 9)]
    await _open_close(path)  # opened again: nothing sealed twice
    with contextlib.closing(sqlite3.connect(path)) as db:
        assert db.execute("SELECT id, seal_seq FROM audit ORDER BY id").fetchall() == seals
    tamper(path, "UPDATE audit SET user = 'mallory' WHERE id = 5")
    code, out_text = verify_database(path, tmp_path, capsys)
    assert code == 1 and "TAMPERED: row 5 changed" in out_text


def verify_database(
    path: Path, state_dir: Path, capsys: pytest.CaptureFixture[str]
) -> tuple[int, str]:
    code = main(["audit", "verify", "--state-dir", str(state_dir), "--database", str(path)])
    captured = capsys.readouterr()
    return code, captured.out + captured.err


def test_a_seal_covers_every_column_of_the_audit_table(tmp_path: Path) -> None:
    """A column added to the audit table by a later migration must be sealed too."""
    path = tmp_path / "hmi.db"
    asyncio.run(_open_close(path))
    with contextlib.closing(sqlite3.connect(path)) as db:
        columns = [row[1] for row in db.execute("PRAGMA table_info(audit)")]
    assert sorted(audit_chain.SEALED) == sorted(set(columns) - {"seal_seq", "seal_hash"})


async def _open_close(path: Path) -> None:
    store = Store(path)
    await store.open()
    await store.close()


async def test_the_head_goes_to_the_log_when_it_moved(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.WARNING, logger="cobot_hmi.service.storage.store")
    store = Store(tmp_path / "hmi.db", chain_head_interval_s=0.05)
    await store.open()
    try:
        await store.keep_audit(entry("login", "ok"))
        await store.keep_audit(entry("logout", "ok"))
        head = await store.read_chain_head()
        wanted = f"audit chain head: seal #2, row 2, sha256 {head.hash[:16]}"
        await eventually(lambda: any(wanted in r.getMessage() for r in caplog.records))
    finally:
        await store.close()


def test_no_database_is_a_clear_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out = verify(tmp_path, capsys)
    assert code == 2 and "no such database" in out


hmi = hmi_fixture()


async def test_the_service_seals_its_rows_and_shows_the_head(hmi: Running) -> None:
    """Through the API: a write's row sealed with its outcome, the CSV export's hash column,
    the head in /metrics."""
    robot = next(iter(hmi.service.robots))
    async with hmi.client(await hmi.login(OPERATOR)) as operator:
        taken = await operator.post(f"/api/v1/robots/{robot}/control/take")
        assert taken.status_code == 200, taken.text
        wrote = await operator.patch(
            f"/api/v1/robots/{robot}/command", json={"controlbox_do": {"2": True}}
        )
        assert wrote.status_code == 200, wrote.text
        page = (await operator.get("/api/v1/audit", params={"limit": 1000})).json()
        exported = await operator.get("/api/v1/audit", params={"format": "csv", "limit": 1000})
    write = next(item for item in page["items"] if item["action"] == "write")
    assert write["outcome"] == "confirmed" and len(write["seal_hash"]) == 64
    rows = list(csv.DictReader(io.StringIO(exported.text)))
    assert {row["id"]: row["seal_hash"] for row in rows} == {
        str(item["id"]): item["seal_hash"] for item in page["items"]
    }
    head = await hmi.service.store.read_chain_head()
    assert head.seq == max(item["seal_seq"] for item in page["items"])
    metrics = await hmi.metrics()
    assert f"cobot_hmi_audit_chain_head_row {float(head.row_id or 0)}" in metrics
    assert f'sha256="{head.hash[:16]}"' in metrics
    assert f'seal="{head.seq}"' in metrics

"""The audit trail on a real full disk: the service's state directory on a small tmpfs, filled
with a file and freed again.

A write or a control change whose ``pending`` row cannot be written is refused with the reason
(503) and nothing changes; a refusal is answered as it is; an outcome the robot already
confirmed when the disk filled is answered as confirmed with ``audit_pending`` and written once
there is room, so no confirmed write is missing from the audit; the MQTT door's DCMD says the
same refusal; a ``pending`` row a crash left is marked ``interrupted`` when the store opens."""

from __future__ import annotations

import asyncio
import contextlib
import json
import math
import secrets
import sqlite3
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import pytest

from cobot_hmi.codec import CommandImage
from cobot_hmi.emulator.static_robot import StaticRobot
from cobot_hmi.emulator.target import Target
from cobot_hmi.service.access.auth import Session
from cobot_hmi.service.access.users import Role, User
from cobot_hmi.service.errors import AuditUnavailableError
from cobot_hmi.service.storage.store import INTERRUPTED, AuditEntry, Store
from cobot_hmi.service.writes.pipeline import Writer
from cobot_hmi.sparkplug.commands import DeviceCommand, execute
from service_support import OPERATOR, Running, emulator, eventually, running_service
from service_support import service_settings as base_settings
from tmpfs_support import fill, free, small_tmpfs

FULL = "the audit trail cannot be written: disk full"


class GatedRobot(StaticRobot):
    """A robot that, while ``hold`` is set, keeps the outputs it is sent without showing them
    until ``show`` (a write's confirmation held back at will)."""

    def __init__(self) -> None:
        super().__init__()
        self.hold = False
        self.held: CommandImage | None = None

    def consume_command(self, image: CommandImage, now_s: float) -> None:
        if self.hold:
            self.held = image
            return
        super().consume_command(image, now_s)

    def show(self, target: Target) -> None:
        self.hold = False
        if self.held is not None:
            super().consume_command(self.held, 0.0)
            target.process_image_changed()


def audit_rows(database: Path) -> list[dict[str, Any]]:
    """The audit table, oldest first, read by a connection of its own (read-only)."""
    with contextlib.closing(
        sqlite3.connect(f"{database.resolve().as_uri()}?mode=ro", uri=True)
    ) as db:
        db.row_factory = sqlite3.Row
        return [dict(row) for row in db.execute("SELECT * FROM audit ORDER BY id")]


def outcome_of(database: Path, row_id: int) -> str:
    (row,) = [r for r in audit_rows(database) if r["id"] == row_id]
    return str(row["outcome"])


@contextlib.contextmanager
def full(disk: Path) -> Iterator[None]:
    filler = fill(disk)
    try:
        yield
    finally:
        free(filler)


async def metric(hmi: Running, name: str) -> float:
    for line in (await hmi.metrics()).splitlines():
        if line.startswith(f"cobot_hmi_{name} "):
            return float(line.split()[1])
    raise AssertionError(f"no metric {name}")


@dataclass
class Cell:
    """What the steps of the service test share."""

    hmi: Running
    client: httpx.AsyncClient
    robot: GatedRobot
    target: Target
    disk: Path

    @property
    def runtime(self) -> Any:
        (runtime,) = self.hmi.service.robots.values()
        return runtime

    @property
    def base(self) -> str:
        return f"/api/v1/robots/{self.runtime.name}"

    @property
    def database(self) -> Path:
        return self.hmi.settings.web.database_path

    async def write(self, index: int) -> httpx.Response:
        return await self.client.patch(
            f"{self.base}/command", json={"controlbox_do": {str(index): True}}
        )

    async def control(self, verb: str) -> httpx.Response:
        return await self.client.post(f"{self.base}/control/{verb}")


async def test_a_full_disk_refuses_what_it_cannot_audit_and_loses_no_confirmed_write(
    robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    robot = GatedRobot()
    with small_tmpfs(tmp_path / "state", 16) as disk:
        async with emulator(robot_host, robot) as target:
            settings = base_settings(
                robot_host,
                target.tcp_port,
                plc_host,
                disk,
                history_dir=tmp_path / "history",  # the recorder's pause is another test's
                write_timeout_ms=60_000.0,  # the held confirmation waits for the test
            )
            async with (
                running_service(settings) as hmi,
                hmi.client(await hmi.login(OPERATOR)) as client,
            ):
                cell = Cell(hmi, client, robot, target, disk)
                await _refusals_while_full(cell)
                # Room again: control, a write, both audited at once.
                assert (await cell.control("take")).status_code == 200
                first = await cell.write(0)
                assert first.status_code == 200, first.text
                assert "audit_pending" not in first.json()
                await _nothing_applied_while_full(cell)
                confirmed = await _confirmed_while_the_disk_fills(cell)
            rows = audit_rows(settings.web.database_path)
    # Every write answered as confirmed is in the audit as confirmed; none is left pending.
    writes = [r for r in rows if r["action"] == "write"]
    answered = [{"controlbox_do.0": True}, {"controlbox_do.2": True}]
    assert [r["outcome"] for r in writes if json.loads(r["requested"]) in answered] == [
        "confirmed",
        "confirmed",
    ]
    assert confirmed in {r["id"] for r in writes if r["outcome"] == "confirmed"}
    assert not [r for r in rows if r["outcome"] == "pending"]
    # The refusals the full disk caused are in too (kept in memory, written once it had room).
    refusals = [(r["action"], r["outcome"]) for r in rows if (r["reason"] or "").startswith(FULL)]
    assert ("control.take", "refused") in refusals and ("write", "refused") in refusals
    assert ("control.release", "refused") in refusals
    assert [r for r in rows if r["outcome"] == "invalid"]


async def _refusals_while_full(cell: Cell) -> None:
    with full(cell.disk):
        take = await cell.control("take")
        assert take.status_code == 503, take.text
        reason = take.json()["detail"]["reason"]
        assert reason.startswith(FULL) and reason.endswith("control was not taken")
        assert cell.runtime.control.holder is None
        # A refusal is answered as it is, its row kept until there is room.
        invalid = await cell.write(99)
        assert invalid.status_code == 422, invalid.text
        no_control = await cell.write(0)
        assert no_control.status_code == 409, no_control.text
        # The MQTT door: a DCMD is refused with the same reason.
        mqtt = await execute(
            cell.runtime,
            _mqtt_writer(),
            DeviceCommand(body={"controlbox_do": {"4": True}}, take=True),
            origin="MQTT DCMD test",
            writes_enabled=True,
        )
        assert mqtt.outcome == "refused" and mqtt.reason.startswith(FULL)
        assert cell.runtime.control.holder is None
        assert await metric(cell.hmi, "audit_backlog") >= 4


async def _nothing_applied_while_full(cell: Cell) -> None:
    runtime = cell.runtime
    with full(cell.disk):
        # Nothing is applied without its pending row; control stays.
        refused = await cell.write(1)
        assert refused.status_code == 503, refused.text
        reason = refused.json()["detail"]["reason"]
        assert reason.startswith(FULL) and "the write was not applied" in reason
        assert runtime.link.command.controlbox_do[1] is False
        release = await cell.control("release")
        assert release.status_code == 503
        assert "control was not released" in release.json()["detail"]["reason"]
        assert runtime.control.holder is not None
    await eventually(lambda: not runtime.store.audit_backlog.items)


async def _confirmed_while_the_disk_fills(cell: Cell) -> int:
    """A write whose pending row is written, then the disk fills before the robot confirms:
    answered as confirmed with ``audit_pending``, its outcome written once there is room; the
    row's id."""
    database = cell.database
    cell.robot.hold = True
    writing = asyncio.create_task(cell.write(2))
    await eventually(lambda: any(r["outcome"] == "pending" for r in audit_rows(database)))
    (pending,) = [r["id"] for r in audit_rows(database) if r["outcome"] == "pending"]
    with full(cell.disk):
        cell.robot.show(cell.target)
        answer = await writing
        assert answer.status_code == 200, answer.text
        body = answer.json()
        assert body["outcome"] == "confirmed" and body["audit_pending"] is True
        assert "disk full" in body["warning"]
        assert body["image"]["controlbox_do"][2] is True
        assert await metric(cell.hmi, "audit_backlog") >= 1
        assert outcome_of(database, pending) == "pending"
    # Room again: written within the store's retry period, before anything else.
    await eventually(lambda: outcome_of(database, pending) == "confirmed")
    assert await metric(cell.hmi, "audit_backlog") == 0
    return int(pending)


def _mqtt_writer() -> Writer:
    user = User("mqtt:test", Role.OPERATOR)
    session = Session(secrets.token_urlsafe(24), user, time.time(), math.inf)
    return Writer(user.name, user.role, "mqtt://127.0.0.1 (test)", session)


async def test_the_store_keeps_what_happened_and_refuses_what_would_act(tmp_path: Path) -> None:
    with small_tmpfs(tmp_path / "disk", 4) as disk:
        store = Store(disk / "hmi.db")
        await store.open()
        try:
            row = await store.add_audit(_entry("pending"), fsync=False)
            with full(disk):
                with pytest.raises(AuditUnavailableError) as refused:
                    await store.add_audit(_entry("pending"))
                assert refused.value.status == 503 and refused.value.reason.startswith(FULL)
                assert await store.finish_audit(row, "confirmed", None) is False
                assert await store.keep_audit(_entry("refused"), happened=False) is False
                assert len(store.audit_backlog) == 2
                # Still full: nothing new is admitted before what waits is in.
                with pytest.raises(AuditUnavailableError):
                    await store.add_audit(_entry("pending"))
            await eventually(lambda: not store.audit_backlog.items)
            page = await store.audit_page(10, 0)
            assert sorted(str(item["outcome"]) for item in page.items) == ["confirmed", "refused"]
            # Full again at the stop: what waits goes to the log, the row stays pending...
            second = await store.add_audit(_entry("pending"), fsync=False)
            with full(disk):
                assert await store.finish_audit(second, "confirmed", None) is False
                await store.close()
        finally:
            await store.close()
        # ...and the next start marks it interrupted.
        reopened = Store(disk / "hmi.db")
        await reopened.open()
        try:
            items = {item["id"]: item for item in (await reopened.audit_page(10, 0)).items}
        finally:
            await reopened.close()
    assert items[row]["outcome"] == "confirmed"
    assert items[second]["outcome"] == INTERRUPTED
    assert "stopped before the outcome was written" in str(items[second]["reason"])


def _entry(outcome: str) -> AuditEntry:
    return AuditEntry("olivia", "127.0.0.1", "write", ["controlbox_do.0"], None, {}, outcome, None)

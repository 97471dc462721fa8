"""Issue 13, alarms end to end: the simulated robot behind the real EtherNet/IP target (its
control API drives the e-stop), the service on loopback holding the class 1 connection. An
e-stop raises its alarm with the very frame that shows it, on the stream and in the API;
acknowledge, reset and a restart of the service keep the ISA-18.2 states; shelving expires;
per-robot filtering; the history as CSV with ISO 8601 times; /metrics and the status' packet
loss fields."""

from __future__ import annotations

import asyncio
import contextlib
import csv
import io
from collections.abc import AsyncIterator
from datetime import datetime
from pathlib import Path
from typing import Any

import orjson
import pytest
from websockets.asyncio.client import connect

from cobot_hmi.service.alarms.persistence import HISTORY_CSV_COLUMNS
from cobot_hmi.service.api.models import EVENT, STREAM_MESSAGE, AlarmHistoryPage, AlarmList
from cobot_hmi.settings import HmiSettings
from conftest import free_tcp_port
from emulator_harness import Emulator, running_emulator
from frame_support import CollectedFrames
from service_support import (
    ADMIN,
    OPERATOR,
    VIEWER,
    Running,
    cell_settings,
    emulator,
    eventually,
    running_service,
    service_settings,
)
from tmpfs_support import fill, free, small_tmpfs

pytestmark = pytest.mark.timeout(180)

ESTOP = "robot:emergency_stop"
DOOR = {
    "name": "door-open",
    "field": "controlbox_di",
    "index": 2,  # DI 3
    "active_when": True,
    "priority": "high",
    "message": "Cell door open",
}
"""A user alarm on an input the emulator sets at will (``POST /inputs``)."""


class Stream:
    """A WebSocket reader keeping every message, each validated against the contract."""

    def __init__(self) -> None:
        self.messages: list[Any] = []
        self.invalid: list[str] = []

    def alarm_events(self, alarm_id: str | None = None) -> list[dict[str, Any]]:
        return [
            m["event"]
            for m in self.messages
            if m["type"] == "event"
            and m["event"]["kind"] == "alarm"
            and (alarm_id is None or m["event"]["alarm"]["id"] == alarm_id)
        ]


@contextlib.asynccontextmanager
async def stream(url: str, token: str | None = None) -> AsyncIterator[Stream]:
    headers = {"Authorization": f"Bearer {token}"} if token else None
    reading = Stream()
    async with connect(url, additional_headers=headers) as connection:

        async def read() -> None:
            async for text in connection:
                message = orjson.loads(text)
                reading.messages.append(message)
                try:
                    STREAM_MESSAGE.validate_python(message)
                except ValueError as error:
                    reading.invalid.append(f"{str(message)[:200]}: {error}")

        task = asyncio.create_task(read())
        try:
            yield reading
        finally:
            await connection.close()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await asyncio.wait_for(task, 5)
    assert not reading.invalid, reading.invalid[:3]


async def alarms(hmi: Running, query: str = "") -> dict[str, dict[str, Any]]:
    async with hmi.client() as client:
        answer = await client.get(f"/api/v1/alarms{query}")
    assert answer.status_code == 200, answer.text
    AlarmList.model_validate(answer.json())
    return {item["id"]: item for item in answer.json()["items"]}


def state_is(hmi: Running, value: int) -> bool:
    latest = hmi.service.default_robot.frames.latest
    return latest is not None and latest[2].robot_state == value


@pytest.fixture
async def emu(robot_host: str, plc_host: str) -> AsyncIterator[Emulator]:
    async with running_emulator(robot_host, plc_host) as emulator_:
        yield emulator_


def emulated_settings(
    emu: Emulator, plc_host: str, tmp_path: Path, **overrides: Any
) -> HmiSettings:
    """The service's settings for ``emu``'s robot. A connection slow to come up on a busy
    machine must not add an alarm of its own here (unless ``overrides`` say otherwise)."""
    return service_settings(
        emu.target.settings.host,
        emu.target.tcp_port,
        plc_host,
        tmp_path,
        **{"alarm_connection_delay_s": 600, **overrides},
    )


async def test_estop_alarm_ack_restart_reset(emu: Emulator, plc_host: str, tmp_path: Path) -> None:
    settings = emulated_settings(emu, plc_host, tmp_path)
    async with running_service(settings) as hmi:
        await eventually(lambda: state_is(hmi, 14))  # STANDALONE_RUNNING
        assert ESTOP not in await alarms(hmi)
        robot = hmi.service.default_robot
        frames = CollectedFrames(robot.frames, 100_000)
        async with stream(hmi.robot_ws_url("robot")) as watching:
            await emu.post("/estop")
            await eventually(lambda: bool(watching.alarm_events(ESTOP)))
        frames.close()
        first_estop_t = next(
            item[1]
            for item in frames.take()
            if item[2].robot_state == 0 or item[2].emergency_stopped
        )
        [event] = watching.alarm_events(ESTOP)
        EVENT.validate_python(event)
        assert event["transition"] == "activated"
        # Raised by the first frame that shows the e-stop: the alarm's time is that frame's.
        assert event["alarm"]["activated_at"] == first_estop_t
        assert event["alarm"]["state"] == "active_unacknowledged"
        assert event["alarm"]["priority"] == "critical" and event["alarm"]["colour"] == "red"
        current = await alarms(hmi)
        assert current[ESTOP]["state"] == "active_unacknowledged"
        assert current[ESTOP]["active"] is True and current[ESTOP]["acknowledged"] is False
        # The most urgent first.
        assert next(iter(current)) == ESTOP
        # A stream opened now has them in its hello; the robot's summary counts them.
        async with stream(hmi.robot_ws_url("robot")) as late:
            await eventually(lambda: bool(late.messages))
        hello = late.messages[0]
        assert hello["type"] == "hello" and hello["alarms"][0]["id"] == ESTOP
        async with hmi.client() as client:
            summary = (await client.get("/api/v1/robots/robot")).json()["alarms"]
        assert summary["active"] >= 1 and summary["unacknowledged"] >= 1
        assert summary["highest_priority"] == "critical"
        activated_at = current[ESTOP]["activated_at"]

    # A restart keeps the active, unacknowledged alarm: not raised again, same time.
    again = settings.replace(port=free_tcp_port(plc_host))
    async with running_service(again) as hmi:
        await eventually(lambda: state_is(hmi, 0))
        kept = (await alarms(hmi))[ESTOP]
        assert kept["state"] == "active_unacknowledged"
        assert kept["activated_at"] == activated_at
        async with hmi.client(await hmi.login(VIEWER)) as viewer:
            refused = await viewer.post(f"/api/v1/alarms/{ESTOP}/ack", json={})
        assert refused.status_code == 403, refused.text
        async with hmi.client(await hmi.login(OPERATOR)) as operator:
            acked = await operator.post(
                f"/api/v1/alarms/{ESTOP}/ack", json={"comment": "cell checked"}
            )
            assert acked.status_code == 200, acked.text
            alarm = acked.json()["alarm"]
            assert acked.json()["changed"] is True
            assert alarm["state"] == "active_acknowledged"
            assert (alarm["acknowledged_by"], alarm["ack_comment"]) == (OPERATOR[0], "cell checked")
            twice = await operator.post(f"/api/v1/alarms/{ESTOP}/ack")  # no body: fine
            assert twice.status_code == 200 and twice.json()["changed"] is False
            audit = (await operator.get("/api/v1/audit?limit=5")).json()["items"]
        acks = [row for row in audit if row["action"] == "alarm.ack"]
        assert [(r["user"], r["outcome"]) for r in acks] == [
            (OPERATOR[0], "unchanged"),
            (OPERATOR[0], "acknowledged"),
            (VIEWER[0], "forbidden"),
        ]
        assert acks[1]["requested"] == {"comment": "cell checked"}
        assert acks[1]["fields"] == ["emergency_stop"] and acks[1]["robot"] == "robot"
        assert acks[1]["summary"] == "Emergency stop: acknowledged — cell checked"

        # Reset: the e-stop returns to normal (acknowledged before: C → A); SAFE_OFF passes by
        # as its consequence, suppressed by design (A → G → A): nothing is left to acknowledge.
        await emu.post("/reset")
        await eventually(lambda: state_is(hmi, 13))  # STANDALONE_STANDBY
        await eventually(
            lambda: hmi.service.default_robot.alarms.find(ESTOP).status.state == "normal"
        )
        safe_off = hmi.service.default_robot.alarms.find("robot:safe_off").status
        await eventually(lambda: safe_off.state == "normal" and safe_off.cleared_at is not None)
        current = await alarms(hmi)
        assert ESTOP not in current and "robot:safe_off" not in current
        everything = await alarms(hmi, "?which=all")
        assert everything[ESTOP]["state"] == "normal"
        assert everything[ESTOP]["message"] == "robot state now Safe off (servo off)"
        assert everything["robot:safe_off"]["suppressed_by"] == ESTOP

        await hmi.service.default_robot.alarm_store.flush()
        async with hmi.client() as client:
            page = (await client.get("/api/v1/alarms/history?robot=robot")).json()
            AlarmHistoryPage.model_validate(page)
            history_csv = await client.get("/api/v1/alarms/history?format=csv")
        transitions = [(i["key"], i["transition"]) for i in reversed(page["items"])]
        estop_transitions = [t for k, t in transitions if k == "emergency_stop"]
        assert estop_transitions == ["activated", "acknowledged", "cleared"]
        safe_off_rows = [
            (i["transition"], i["state"], i["suppressed_by"])
            for i in reversed(page["items"])
            if i["key"] == "safe_off"
        ]
        assert safe_off_rows == [("activated", "suppressed", ESTOP), ("cleared", "normal", None)]
        assert history_csv.status_code == 200
        assert history_csv.headers["content-type"].startswith("text/csv")
        rows = list(csv.reader(io.StringIO(history_csv.text)))
        assert tuple(rows[0]) == HISTORY_CSV_COLUMNS
        assert len(rows) - 1 == page["total"] == int(history_csv.headers["x-total-count"])
        for row in rows[1:]:
            when = datetime.fromisoformat(row[1])
            assert when.tzinfo is not None and when.utcoffset() is not None
        metrics = await hmi.metrics()
        assert 'cobot_hmi_alarms{priority="high",robot="robot",state="unacknowledged"} 0.0' in (
            metrics
        )
        assert 'cobot_hmi_alarms{priority="critical",robot="robot",state="active"} 0.0' in metrics


async def test_an_acknowledgement_on_a_full_disk_is_answered_and_kept(
    emu: Emulator, plc_host: str, tmp_path: Path
) -> None:
    """The disk full when an operator acknowledges: the acknowledgement takes effect and is
    answered as such; its audit row and its history row wait in memory and are in the
    database once the disk has room (nothing lost, nothing answered as refused)."""
    with small_tmpfs(tmp_path / "state", 16) as disk:
        settings = emulated_settings(emu, plc_host, disk, history_dir=tmp_path / "history")
        async with running_service(settings) as hmi:
            await eventually(lambda: state_is(hmi, 14))  # STANDALONE_RUNNING
            await emu.post("/estop")
            engine = hmi.service.default_robot.alarms
            await eventually(lambda: engine.find(ESTOP).status.state.active)
            async with hmi.client(await hmi.login(OPERATOR)) as operator:
                filler = fill(disk)
                try:
                    acked = await operator.post(
                        f"/api/v1/alarms/{ESTOP}/ack", json={"comment": "on a full disk"}
                    )
                    assert acked.status_code == 200, acked.text
                    assert acked.json()["changed"] is True
                    assert acked.json()["alarm"]["state"] == "active_acknowledged"
                    assert hmi.service.store.audit_backlog.items  # waiting, not lost
                finally:
                    free(filler)
                await eventually(lambda: not hmi.service.store.audit_backlog.items)
                await eventually(lambda: not hmi.service.default_robot.alarm_store.writer.waiting)
                audit = (await operator.get("/api/v1/audit?limit=10")).json()["items"]
                history = (await operator.get("/api/v1/alarms/history?robot=robot")).json()
        acks = [(r["action"], r["outcome"], r["requested"]) for r in audit]
        assert ("alarm.ack", "acknowledged", {"comment": "on a full disk"}) in acks
        transitions = [(h["key"], h["transition"]) for h in history["items"]]
        assert ("emergency_stop", "acknowledged") in transitions
        assert hmi.service.default_robot.alarm_store.write_errors == 0


async def test_shelving_with_expiry_and_refusals(
    emu: Emulator, plc_host: str, tmp_path: Path
) -> None:
    # A high alarm the emulator raises at will (the safety stops are never shelved).
    settings = emulated_settings(emu, plc_host, tmp_path, alarm_shelve_max_s=60, alarms=[DOOR])
    async with running_service(settings) as hmi:
        alarm_id = "robot:user.door-open"
        async with hmi.client(await hmi.login(OPERATOR)) as operator:
            path = f"/api/v1/alarms/{alarm_id}/shelve"
            for body, field in (
                ({"duration_s": 1.0}, "reason"),
                ({"reason": "", "duration_s": 1.0}, "reason"),
                ({"reason": "x", "duration_s": 0}, "duration_s"),
                ({"reason": "x", "duration_s": 61}, "duration_s"),
            ):
                answer = await operator.post(path, json=body)
                assert answer.status_code == 422, (body, answer.text)
                assert answer.json()["detail"]["field"] == field
            unknown = await operator.post(
                "/api/v1/alarms/robot:nope/shelve", json={"reason": "x", "duration_s": 1}
            )
            assert unknown.status_code == 404
            shelved = await operator.post(
                path, json={"reason": "guard being replaced", "duration_s": 59}
            )
            assert shelved.status_code == 200, shelved.text
            assert shelved.json()["alarm"]["shelved"] is True
            assert shelved.json()["alarm"]["shelve_reason"] == "guard being replaced"
            # While shelved the alarm still follows its condition.
            await emu.post("/inputs", {"controlbox_di": {"2": True}})
            await eventually(
                lambda: hmi.service.default_robot.alarms.find(alarm_id).status.state.active
            )
            item = (await alarms(hmi))[alarm_id]
            assert item["shelved"] is True and item["state"] == "active_unacknowledged"
            # Shelved again, briefly: the expiry unshelves it.
            again = await operator.post(path, json={"reason": "nearly done", "duration_s": 0.5})
            assert again.json()["alarm"]["shelve_reason"] == "nearly done"
            # The expiry unshelves it (the slow tick; a generous deadline).
            await eventually(
                lambda: not hmi.service.default_robot.alarms.find(alarm_id).status.shelved,
                timeout_s=30,
            )
            await hmi.service.default_robot.alarm_store.flush()
            page = (await operator.get("/api/v1/alarms/history?limit=50")).json()
            audit = (await operator.get("/api/v1/audit?limit=20")).json()["items"]
        kinds = [i["transition"] for i in reversed(page["items"]) if i["alarm_id"] == alarm_id]
        assert kinds[0] == "shelved" and "shelve_expired" in kinds and "activated" in kinds
        shelve_rows = [(r["outcome"], r["reason"]) for r in audit if r["action"] == "alarm.shelve"]
        assert shelve_rows[0] == ("shelved", None)
        assert shelve_rows[1] == ("shelved", None)
        longest = (
            "a high alarm is shelved for more than 0 and at most 60 s (1 min, alarm_shelve_max_s)"
        )
        assert ("refused", longest) in shelve_rows


async def test_unshelve_is_authorized_and_audited_like_ack_and_shelve(
    emu: Emulator, plc_host: str, tmp_path: Path
) -> None:
    """Each row of an unshelve: a viewer's refusal (nothing asked: null), a no-op (``{}``,
    "not shelved"), the real one with its summary."""
    settings = emulated_settings(emu, plc_host, tmp_path)
    async with running_service(settings) as hmi:
        alarm_id = "robot:safe_off"
        path = f"/api/v1/alarms/{alarm_id}/unshelve"
        async with hmi.client(await hmi.login(VIEWER)) as viewer:
            refused = await viewer.post(path)
        assert refused.status_code == 403, refused.text
        async with hmi.client(await hmi.login(OPERATOR)) as operator:
            noop = await operator.post(path)
            assert noop.status_code == 200 and noop.json()["changed"] is False, noop.text
            shelved = await operator.post(
                f"/api/v1/alarms/{alarm_id}/shelve", json={"reason": "guard out", "duration_s": 60}
            )
            assert shelved.status_code == 200, shelved.text
            done = await operator.post(path)
            assert done.status_code == 200 and done.json()["changed"] is True, done.text
            assert done.json()["alarm"]["shelved"] is False
            missing = await operator.post("/api/v1/alarms/robot:nope/unshelve")
            assert missing.status_code == 404
            audit = (await operator.get("/api/v1/audit?limit=10")).json()["items"]
        rows = [
            (r["user"], r["outcome"], r["reason"], r["requested"], r["fields"], r["summary"])
            for r in reversed(audit)
            if r["action"] == "alarm.unshelve"
        ]
        assert rows[0][:5] == (VIEWER[0], "forbidden", rows[0][2], None, ["safe_off"])
        assert rows[0][2] and "operator" in rows[0][2]
        words = "Servo off after an error (SAFE_OFF): unshelved"
        assert rows[1:] == [
            (OPERATOR[0], "unchanged", "not shelved", {}, ["safe_off"], words),
            (OPERATOR[0], "unshelved", None, {}, ["safe_off"], words),
        ]
        assert {r["origin"] for r in audit if r["action"] == "alarm.unshelve"} == {f"POST {path}"}


async def test_alarms_per_robot(robot_host: str, plc_host: str, tmp_path: Path) -> None:
    from conftest import _next_host

    async with running_emulator(robot_host, plc_host) as left, emulator(_next_host()) as right:
        settings = cell_settings(
            [
                ("left", left.target.settings.host, left.target.tcp_port),
                ("right", right.settings.host, right.tcp_port),
            ],
            plc_host,
            tmp_path,
        )
        async with running_service(settings) as hmi:
            left_robot = hmi.service.robots["left"]
            await eventually(
                lambda: (
                    left_robot.frames.latest is not None
                    and left_robot.frames.latest[2].robot_state == 14
                )
            )
            await left.post("/estop")
            await eventually(
                lambda: left_robot.alarms.find("left:emergency_stop").status.state.active
            )
            mine = await alarms(hmi, "?robot=left")
            theirs = await alarms(hmi, "?robot=right")
            both = await alarms(hmi)
            assert "left:emergency_stop" in mine and "left:emergency_stop" in both
            assert all(a["robot"] == "left" for a in mine.values())
            assert all(a["robot"] == "right" and k.startswith("right:") for k, a in theirs.items())
            assert set(mine) | set(theirs) == set(both)
            async with hmi.client() as client:
                one = await client.get("/api/v1/alarms/left:emergency_stop")
                assert one.status_code == 200 and one.json()["state"] == "active_unacknowledged"
                for missing in ("left:nope", "nobody:emergency_stop", "emergency_stop"):
                    answer = await client.get(f"/api/v1/alarms/{missing}")
                    assert answer.status_code == 404, missing
                    assert answer.json()["detail"]["field"] == "alarm_id"
                unknown = await client.get("/api/v1/alarms?robot=nobody")
                assert unknown.status_code == 404
                assert unknown.json()["detail"]["known"] == ["left", "right"]
                status = (await client.get("/api/v1/robots/right/status")).json()
            assert status["connection"]["packet_loss_high"] is False
            await eventually(lambda: hmi.service.robots["right"].alarms.gaps_per_min is not None)
            async with hmi.client() as client:
                status = (await client.get("/api/v1/robots/right/status")).json()
            assert status["connection"]["gaps_per_min"] == 0.0


async def test_user_alarm_from_the_settings_with_its_tag(
    emu: Emulator, plc_host: str, tmp_path: Path
) -> None:
    door = {
        "name": "door-open",
        "field": "controlbox_di",
        "index": 2,  # DI 3
        "active_when": True,
        "on_delay_s": 0.2,
        "priority": "high",
        "message": "Cell door open",
    }
    pressure = {"name": "pressure", "field": "analog_input", "index": 1, "low": 4.5, "high": 18}
    settings = service_settings(
        emu.target.settings.host,
        emu.target.tcp_port,
        plc_host,
        tmp_path,
        alarms=[door, pressure],
    )
    alarm_id = "robot:user.door-open"
    async with running_service(settings) as hmi:
        async with hmi.client(await hmi.login(ADMIN)) as admin:
            named = await admin.put(
                "/api/v1/robots/robot/tags", json={"tags": {"controlbox_di.2": "cell door"}}
            )
            assert named.status_code == 200
        engine = hmi.service.default_robot.alarms
        assert not engine.find(alarm_id).status.state.active
        await emu.post("/inputs", {"controlbox_di": {"2": True}})
        await eventually(lambda: engine.find(alarm_id).status.state.active)
        alarm = (await alarms(hmi))[alarm_id]
        assert alarm["name"] == "Cell door open" and alarm["priority"] == "high"
        assert alarm["label"] == "DI 3" and alarm["tag"] == "cell door"
        assert alarm["message"] == "DI 3 (cell door) = on"
        await emu.post("/inputs", {"controlbox_di": {"2": False}})
        await eventually(lambda: not engine.find(alarm_id).status.state.active)
        assert (await alarms(hmi))[alarm_id]["state"] == "returned_unacknowledged"
        everything = await alarms(hmi, "?which=all")
        assert everything["robot:user.pressure"]["low"] == 4.5
        async with hmi.client(await hmi.login(OPERATOR)) as operator:
            normal = await operator.post("/api/v1/alarms/robot:motor_temperature.0/ack", json={})
            assert normal.status_code == 409
            assert "nothing to acknowledge" in normal.json()["detail"]["reason"]
            audit = (await operator.get("/api/v1/audit?limit=1")).json()["items"]
        assert (audit[0]["action"], audit[0]["outcome"]) == ("alarm.ack", "refused")


async def test_refused_forward_open_and_lost_connection_alarms(
    robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    async with emulator(robot_host) as target:
        # A T→O size the robot does not have: every Forward Open is refused.
        settings = service_settings(robot_host, target.tcp_port, plc_host, tmp_path, t2o_size=100)
        async with running_service(settings, wait_connected=False) as hmi:
            engine = hmi.service.default_robot.alarms
            await eventually(lambda: engine.find("robot:forward_open_refused").status.state.active)
            await eventually(
                lambda: engine.find("robot:connection_lost").status.state.active, timeout_s=30
            )
            current = await alarms(hmi)
            refused = current["robot:forward_open_refused"]
            assert refused["message"].startswith("Forward Open refused: ")
            assert current["robot:connection_lost"]["message"].startswith("not connected")

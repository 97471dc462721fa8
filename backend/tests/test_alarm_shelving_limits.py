"""Shelving's limits (ISA-18.2 §11.4.3), against the real service and the emulator over real
sockets: the safety stops and critical alarms are never shelved (409 with the reason), each
priority has its longest shelving (a setting; 422 naming it), and a shelved alarm whose
condition clears and comes again is annunciated again (active, unacknowledged, on the banner
and announced on the stream), as an e-stop 21 minutes after its shelving was not (issue 38)."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import orjson
import pytest
from websockets.asyncio.client import connect

from cobot_hmi.service.api.models import Alarm
from emulator_harness import Emulator, running_emulator
from service_support import OPERATOR, Running, eventually, running_service, service_settings

pytestmark = pytest.mark.timeout(180)

DOOR = {
    "name": "door-open",
    "field": "controlbox_di",
    "index": 2,  # DI 3
    "active_when": True,
    "priority": "high",
    "message": "Cell door open",
}
LEVEL = {**DOOR, "name": "level-low", "index": 3, "priority": "medium", "message": "Level low"}
GUARD = {**DOOR, "name": "guard-open", "index": 4, "priority": "critical", "message": "Guard"}
DOOR_ID = "robot:user.door-open"


@pytest.fixture
async def emu(robot_host: str, plc_host: str) -> AsyncIterator[Emulator]:
    async with running_emulator(robot_host, plc_host) as emulator_:
        yield emulator_


def settings_for(emu: Emulator, plc_host: str, tmp_path: Path, **overrides: Any) -> Any:
    return service_settings(
        emu.target.settings.host,
        emu.target.tcp_port,
        plc_host,
        tmp_path,
        alarms=[DOOR, LEVEL, GUARD],
        **{"alarm_connection_delay_s": 600, **overrides},
    )


async def shelve(hmi: Running, token: str, alarm_id: str, duration_s: float) -> Any:
    async with hmi.client(token) as client:
        return await client.post(
            f"/api/v1/alarms/{alarm_id}/shelve",
            json={"reason": "issue 38", "duration_s": duration_s},
        )


async def one_alarm(hmi: Running, alarm_id: str) -> dict[str, Any]:
    async with hmi.client() as client:
        answer = await client.get(f"/api/v1/alarms/{alarm_id}")
    assert answer.status_code == 200, answer.text
    Alarm.model_validate(answer.json())
    item: dict[str, Any] = answer.json()
    return item


async def test_safety_stops_and_critical_alarms_are_never_shelved(
    emu: Emulator, plc_host: str, tmp_path: Path
) -> None:
    async with running_service(settings_for(emu, plc_host, tmp_path)) as hmi:
        token = await hmi.login(OPERATOR)
        await emu.post("/estop")
        await eventually(
            lambda: (
                hmi.service.default_robot.alarms.find("robot:emergency_stop").status.shelved
                is False
                and hmi.service.default_robot.alarms.find(
                    "robot:emergency_stop"
                ).status.state.active
            )
        )
        for alarm_id, words in (
            ("robot:emergency_stop", "Emergency stop is a safety stop: it cannot be shelved"),
            ("robot:protective_stop", "Protective stop is a safety stop: it cannot be shelved"),
            ("robot:user.guard-open", "Guard is a critical alarm: it cannot be shelved"),
        ):
            refused = await shelve(hmi, token, alarm_id, 900)
            assert refused.status_code == 409, (alarm_id, refused.text)
            assert words in refused.json()["detail"]["reason"]
            item = await one_alarm(hmi, alarm_id)
            assert item["shelved"] is False
            assert item["shelve_max_s"] is None and words in item["shelve_refusal"]
        estop = await one_alarm(hmi, "robot:emergency_stop")
        assert estop["state"] == "active_unacknowledged"
        async with hmi.client() as client:
            summary = (await client.get("/api/v1/alarms/summary")).json()
        assert summary["top"]["id"] == "robot:emergency_stop"  # still on every banner
        async with hmi.client(token) as client:
            audit = (await client.get("/api/v1/audit?limit=10")).json()["items"]
        refusals = [r for r in audit if r["action"] == "alarm.shelve"]
        assert len(refusals) == 3
        assert all(
            r["outcome"] == "refused" and "cannot be shelved" in r["reason"] for r in refusals
        )


async def test_each_priority_has_its_longest_shelving(
    emu: Emulator, plc_host: str, tmp_path: Path
) -> None:
    """High: 1 h by default; medium: its own setting; over it, 422 naming the maximum."""
    settings = settings_for(emu, plc_host, tmp_path, alarm_shelve_max_medium_s=600)
    async with running_service(settings) as hmi:
        token = await hmi.login(OPERATOR)
        door = await one_alarm(hmi, DOOR_ID)
        assert door["shelve_max_s"] == 3600 and door["shelve_refusal"] is None
        over = await shelve(hmi, token, DOOR_ID, 3601)
        assert over.status_code == 422, over.text
        detail = over.json()["detail"]
        assert detail["field"] == "duration_s"
        assert "at most 3600 s (1 h, alarm_shelve_max_high_s)" in detail["reason"]
        assert (await shelve(hmi, token, DOOR_ID, 3600)).status_code == 200

        level = "robot:user.level-low"
        assert (await one_alarm(hmi, level))["shelve_max_s"] == 600
        over = await shelve(hmi, token, level, 601)
        assert over.status_code == 422
        assert (
            "at most 600 s (10 min, alarm_shelve_max_medium_s)" in over.json()["detail"]["reason"]
        )
        assert (await shelve(hmi, token, level, 600)).status_code == 200


@contextlib.asynccontextmanager
async def alarm_events(url: str) -> AsyncIterator[list[dict[str, Any]]]:
    """The stream's ``alarm`` events as they come."""
    events: list[dict[str, Any]] = []
    async with connect(url) as connection:

        async def read() -> None:
            async for text in connection:
                message = orjson.loads(text)
                if message["type"] == "event" and message["event"]["kind"] == "alarm":
                    events.append(message["event"])

        task = asyncio.create_task(read())
        try:
            yield events
        finally:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task


async def test_a_shelved_alarm_that_clears_and_comes_again_is_annunciated(
    emu: Emulator, plc_host: str, tmp_path: Path
) -> None:
    async with running_service(settings_for(emu, plc_host, tmp_path)) as hmi:
        engine = hmi.service.default_robot.alarms
        token = await hmi.login(OPERATOR)
        await emu.post("/inputs", {"controlbox_di": {"2": True}})
        await eventually(lambda: engine.find(DOOR_ID).status.state.active)
        assert (await shelve(hmi, token, DOOR_ID, 3600)).status_code == 200
        async with alarm_events(hmi.robot_ws_url("robot")) as events:
            # It clears while shelved: still shelved, not annunciated.
            await emu.post("/inputs", {"controlbox_di": {"2": False}})
            await eventually(lambda: not engine.find(DOOR_ID).status.state.active)
            cleared = await one_alarm(hmi, DOOR_ID)
            assert cleared["shelved"] is True and cleared["state"] == "returned_unacknowledged"
            # A new occurrence: annunciated again.
            await emu.post("/inputs", {"controlbox_di": {"2": True}})
            await eventually(lambda: engine.find(DOOR_ID).status.state.active)
            item = await one_alarm(hmi, DOOR_ID)
            assert item["state"] == "active_unacknowledged"
            assert item["shelved"] is False and item["shelved_until"] is None
            await eventually(lambda: any(e["transition"] == "activated" for e in events))
        activated = next(e for e in events if e["transition"] == "activated")
        assert activated["alarm"]["shelved"] is False
        assert "came again" in activated["comment"]
        async with hmi.client() as client:
            summary = (await client.get("/api/v1/alarms/summary")).json()
        assert summary["top"]["id"] == DOOR_ID and summary["annunciated"] >= 1
        await hmi.service.default_robot.alarm_store.flush()
        async with hmi.client(token) as client:
            history = (await client.get("/api/v1/alarms/history?limit=20")).json()["items"]
        rows = [
            (h["transition"], h["shelved"]) for h in reversed(history) if h["alarm_id"] == DOOR_ID
        ]
        assert rows[-1] == ("activated", False)

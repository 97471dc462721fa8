"""Events, audit trail and alarm history searched by text and time range, paged from the
database and exported as CSV, through the real service (issue 23); the event log and the
alarm history read without a login where anonymous reading is allowed, and refused without
one where it is not (``view_requires_login``); the audit trail always needs an operator."""

from __future__ import annotations

import csv
import io
import time
from collections.abc import AsyncIterator
from datetime import datetime
from pathlib import Path
from typing import Any

import pytest

from cobot_hmi.emulator.target import Target
from cobot_hmi.service.alarms.persistence import AlarmChange
from cobot_hmi.service.storage.store import AuditEntry
from service_support import OPERATOR, Running, running_service, service_settings

pytestmark = pytest.mark.timeout(120)

T0 = time.time() - 3600.0
"""The rows' times: an hour ago, one a minute (so ranges are exact)."""
ROBOT = "robot"


def state_event(minute: int, text: str) -> tuple[float, str, dict[str, object], str]:
    return T0 + 60 * minute, "robot_state", {"state": 1, "text": text}, ROBOT


EVENTS: list[tuple[float, str, dict[str, object], str]] = [
    state_event(0, "Robot state now Manual standby"),
    state_event(1, "Robot state now Standalone running"),
    state_event(2, "Robot state now Protective stop"),
    state_event(3, "Robot state now Standalone running"),
    state_event(4, "Gripper 100%_done"),  # % and _ are taken literally
    # Found by its words, never by a field the words leave out (the alarm's message at the ack).
    (
        T0 + 60 * 5,
        "alarm",
        {
            "transition": "acknowledged",
            "alarm": {"name": "Emergency stop", "message": "robot state now Standalone running"},
            "text": "Emergency stop acknowledged by olivia",
        },
        ROBOT,
    ),
    # Logged before events had a text: found by its fields.
    (T0 + 60 * 6, "flag", {"flag": "legacy_flag", "value": True}, ROBOT),
]


def alarm(minute: int, name: str, comment: str | None = None) -> AlarmChange:
    return AlarmChange(
        time=T0 + 60 * minute,
        robot=ROBOT,
        alarm_id=f"{ROBOT}:{name}",
        key=name,
        name=name,
        priority="high",
        transition="raised",
        state="unack_active",
        shelved=False,
        message=f"{name} raised",
        value=None,
        label=None,
        tag=None,
        user=None,
        comment=comment,
        record={},
    )


async def fill(running: Running) -> None:
    store = running.service.store
    for time_s, kind, data, robot in EVENTS:
        store.submit_event(time_s, kind, data, robot)
    await store.flush_events()
    for minute, (action, summary) in enumerate(
        [("write", "DO 3 = on"), ("control", "took control"), ("write", "DO 4 = off")]
    ):
        await store.add_audit(
            AuditEntry(
                user="olivia",
                client="127.0.0.1",
                action=action,
                fields=[],
                before=None,
                requested=None,
                outcome="confirmed",
                reason=None,
                time=T0 + 60 * minute,
                robot=ROBOT,
                summary=summary,
            )
        )
    alarms = running.service.default_robot.alarm_store
    for change in (
        alarm(0, "e_stop"),
        alarm(2, "motor_temperature", "fan checked"),
        alarm(5, "e_stop"),
    ):
        alarms.submit(change)
    await alarms.flush()


@pytest.fixture
async def hmi(
    target: Target, robot_host: str, plc_host: str, tmp_path: Path
) -> AsyncIterator[Running]:
    settings = service_settings(robot_host, target.tcp_port, plc_host, tmp_path)
    async with running_service(settings) as running:
        await fill(running)
        yield running


async def get(running: Running, path: str, token: str | None = None, **params: Any) -> Any:
    async with running.client(token) as client:
        answer = await client.get(path, params=params)
    assert answer.status_code == 200, answer.text
    return (
        answer.json() if answer.headers["content-type"].startswith("application/json") else answer
    )


def texts(page: dict[str, Any]) -> list[str]:
    return [item["text"] for item in page["items"]]


async def test_events_by_text_range_and_page_without_login(hmi: Running) -> None:
    window: dict[str, Any] = {"from": T0 - 1, "to": T0 + 3600}
    running = await get(hmi, "/api/v1/events", q="standalone RUNNING", **window)
    assert texts(running) == ["Robot state now Standalone running"] * 2
    assert running["total"] == 2
    # A range: from inclusive, to exclusive; ISO 8601 as well as epoch seconds.
    ranged = await get(
        hmi, "/api/v1/events", q="robot state", **{"from": str(T0 + 60), "to": str(T0 + 180)}
    )
    assert texts(ranged) == [
        "Robot state now Protective stop",
        "Robot state now Standalone running",
    ]
    # (half a minute off the rows: ISO 8601 here keeps microseconds, the rows' times more)
    iso_from = datetime.fromtimestamp(T0 + 30).astimezone().isoformat()
    iso_to = datetime.fromtimestamp(T0 + 150).astimezone().isoformat()
    assert (await get(hmi, "/api/v1/events", q="robot state", **{"from": iso_from, "to": iso_to}))[
        "items"
    ] == ranged["items"]
    # Pages of the search, newest first, the total the same on each.
    first = await get(hmi, "/api/v1/events", q="Robot state", limit=3, **window)
    second = await get(hmi, "/api/v1/events", q="Robot state", limit=3, offset=3, **window)
    assert first["total"] == second["total"] == 4
    assert len(first["items"]) == 3 and len(second["items"]) == 1
    assert texts(second) == ["Robot state now Manual standby"]
    # The words of the row, not its fields' keys and values; an older row without words: its fields.
    assert texts(await get(hmi, "/api/v1/events", q="acknowledged by", **window)) == [
        "Emergency stop acknowledged by olivia"
    ]
    assert (await get(hmi, "/api/v1/events", q="transition", **window))["total"] == 0
    legacy = await get(hmi, "/api/v1/events", q="legacy_FLAG", **window)
    assert [item["flag"] for item in legacy["items"]] == ["legacy_flag"]
    # LIKE's wildcards are the text's own characters.
    assert texts(await get(hmi, "/api/v1/events", q="100%_", **window)) == ["Gripper 100%_done"]
    assert (await get(hmi, "/api/v1/events", q="1_0", **window))["total"] == 0
    # CSV of the search.
    answer = await get(hmi, "/api/v1/events", q="protective", format="csv", **window)
    rows = list(csv.DictReader(io.StringIO(answer.text)))
    assert [r["text"] for r in rows] == ["Robot state now Protective stop"]
    assert answer.headers["x-total-count"] == "1"


async def test_audit_needs_an_operator_and_is_searched(hmi: Running) -> None:
    async with hmi.client() as client:
        assert (await client.get("/api/v1/audit")).status_code == 401
    token = await hmi.login(OPERATOR)
    window: dict[str, Any] = {"from": T0 - 1, "to": T0 + 3600}
    writes = await get(hmi, "/api/v1/audit", token, q="DO ", **window)
    assert [i["summary"] for i in writes["items"]] == ["DO 4 = off", "DO 3 = on"]
    ranged = await get(
        hmi, "/api/v1/audit", token, q="olivia", **{"from": str(T0 + 30), "to": str(T0 + 90)}
    )
    assert [i["summary"] for i in ranged["items"]] == ["took control"]


async def test_alarm_history_by_text_and_range(hmi: Running) -> None:
    window: dict[str, Any] = {"from": T0 - 1, "to": T0 + 3600}
    e_stops = await get(hmi, "/api/v1/alarms/history", q="E_STOP", **window)
    assert [i["time"] for i in e_stops["items"]] == pytest.approx([T0 + 300, T0])
    commented = await get(hmi, "/api/v1/alarms/history", q="fan", **window)
    assert [i["key"] for i in commented["items"]] == ["motor_temperature"]
    ranged = await get(hmi, "/api/v1/alarms/history", **{"from": str(T0 + 1), "to": str(T0 + 299)})
    assert [i["key"] for i in ranged["items"]] == ["motor_temperature"]
    answer = await get(hmi, "/api/v1/alarms/history", q="e_stop", format="csv", **window)
    rows = list(csv.DictReader(io.StringIO(answer.text)))
    assert [r["key"] for r in rows] == ["e_stop", "e_stop"]
    assert answer.headers["x-total-count"] == "2"


async def test_reading_needs_a_login_where_the_settings_say_so(
    target: Target, robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    settings = service_settings(
        robot_host, target.tcp_port, plc_host, tmp_path, view_requires_login=True
    )
    async with running_service(settings) as running:
        await fill(running)
        async with running.client() as client:
            assert (await client.get("/api/v1/events", params={"q": "robot"})).status_code == 401
            assert (await client.get("/api/v1/alarms/history")).status_code == 401
            bad = await client.get("/api/v1/events", params={"to": "soon"})
        token = await running.login(OPERATOR)
        found = await get(running, "/api/v1/events", token, q="protective")
    assert texts(found) == ["Robot state now Protective stop"]
    assert bad.status_code in (401, 422)

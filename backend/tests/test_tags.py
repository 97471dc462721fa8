"""Issue 13, tag names and plain words, against the emulator and the service on loopback:
tag names round trip through the API and CSV (admin only, audited, kept across a restart);
a type + value write is named with the spec's labels, the tag names and units in its event
and its audit row; the audit CSV has ISO 8601 times; control belongs to a session, so the
same user in a second window is told so and can neither write nor release."""

from __future__ import annotations

import contextlib
import csv
import io
from collections.abc import AsyncIterator
from datetime import datetime
from pathlib import Path
from typing import Any

import httpx
import orjson
import pytest
from websockets.asyncio.client import connect

from cobot_hmi.emulator.target import Target
from cobot_hmi.service.api.models import AuditPage, EventPage, RobotStatus, TagList
from conftest import free_tcp_port
from service_support import (
    ADMIN,
    OPERATOR,
    Running,
    emulator,
    hmi_fixture,
    running_service,
    service_settings,
)

pytestmark = pytest.mark.timeout(120)


@pytest.fixture
async def target(robot_host: str) -> AsyncIterator[Target]:
    async with emulator(robot_host) as target_:
        yield target_


hmi = hmi_fixture()


async def test_tag_names_round_trip_json_and_csv(
    hmi: Running, target: Target, robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    path = "/api/v1/robots/robot/tags"
    async with hmi.client(await hmi.login(OPERATOR)) as operator:
        listed = (await operator.get(path)).json()
        TagList.model_validate(listed)
        assert listed["tags"] == {}
        do3 = next(p for p in listed["points"] if p["key"] == "controlbox_do.2")
        assert do3["label"] == "DO 3" and do3["directions"] == ["T2O", "O2T"]
        refused = await operator.put(path, json={"tags": {"controlbox_do.2": "gripper close"}})
        assert refused.status_code == 403, refused.text
    async with hmi.client(await hmi.login(ADMIN)) as admin:
        put = await admin.put(
            path,
            json={"tags": {"controlbox_do.2": "gripper close", "bit_input_registers.40": "ready"}},
        )
        assert put.status_code == 200, put.text
        assert put.json()["tags"] == {
            "controlbox_do.2": "gripper close",
            "bit_input_registers.40": "ready",
        }
        bad = await admin.put(path, json={"tags": {"controlbox_do.16": "x"}})
        assert bad.status_code == 422 and bad.json()["detail"]["field"] == "controlbox_do.16"
        exported = await admin.get(path + ".csv")
        assert exported.status_code == 200
        assert exported.headers["content-type"].startswith("text/csv")
        rows = list(csv.reader(io.StringIO(exported.text)))
        assert rows[0] == ["key", "label", "name"]
        assert ["controlbox_do.2", "DO 3", "gripper close"] in rows
        # Edit the sheet: rename DO 3, name Tool DO 1, drop the register's name.
        edited = [
            ["controlbox_do.2", "DO 3", "gripper open"] if r[0] == "controlbox_do.2" else r
            for r in rows
            if r[0] != "bit_input_registers.40"
        ] + [["tool_do.0", "Tool DO 1", "vacuum on"]]
        edited = [r for r in edited if r[0] != "tool_do.0" or r[2]]
        out = io.StringIO()
        csv.writer(out).writerows(edited)
        imported = await admin.post(path + "/import", json={"csv": out.getvalue()})
        assert imported.status_code == 200, imported.text
        assert imported.json()["tags"] == {
            "controlbox_do.2": "gripper open",
            "tool_do.0": "vacuum on",
        }
        # The 0-based trap: a key and a label that disagree are refused, naming the line.
        trap = await admin.post(
            path + "/import", json={"csv": "key,label,name\ncontrolbox_do.3,DO 3,gripper\n"}
        )
        assert trap.status_code == 422
        assert trap.json()["detail"]["field"] == "line 2"
        assert "controlbox_do.3 is DO 4, not DO 3" in trap.json()["detail"]["reason"]
        audit = (await admin.get("/api/v1/audit?limit=10")).json()["items"]
        AuditPage.model_validate({"items": audit, "total": len(audit)})
    updates = [(r["user"], r["outcome"]) for r in audit if r["action"] == "tags.update"]
    # Newest first: the trap sheet, the import, the unknown key, the first names.
    assert updates[:4] == [
        (ADMIN[0], "invalid"),
        (ADMIN[0], "updated"),
        (ADMIN[0], "invalid"),
        (ADMIN[0], "updated"),
    ]
    assert (OPERATOR[0], "forbidden") in updates
    csv_row = next(r for r in audit if r["action"] == "tags.update" and r["outcome"] == "updated")
    assert csv_row["summary"] == (
        "DO 3 = 'gripper open'; Tool DO 1 = 'vacuum on'; Register 40: name removed"
    )
    assert csv_row["labels"]["controlbox_do.2"] == "DO 3"
    assert csv_row["tags"] == {"controlbox_do.2": "gripper open", "tool_do.0": "vacuum on"}


async def test_tag_names_survive_a_restart(
    target: Target, robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    settings = service_settings(robot_host, target.tcp_port, plc_host, tmp_path)
    async with running_service(settings) as hmi, hmi.client(await hmi.login(ADMIN)) as admin:
        answer = await admin.put(
            "/api/v1/robots/robot/tags", json={"tags": {"tool_di.5": "part present"}}
        )
        assert answer.status_code == 200
    again = settings.replace(port=free_tcp_port(plc_host))
    async with running_service(again) as hmi, hmi.client() as client:
        listed = (await client.get("/api/v1/robots/robot/tags")).json()
    assert listed["tags"] == {"tool_di.5": "part present"}


async def test_type_and_value_write_is_named_with_labels_tags_and_units(hmi: Running) -> None:
    async with hmi.client(await hmi.login(ADMIN)) as admin:
        named = await admin.put(
            "/api/v1/robots/robot/tags", json={"tags": {"controlbox_do.2": "gripper close"}}
        )
        assert named.status_code == 200
    async with hmi.client(await hmi.login(OPERATOR)) as operator:
        assert (await operator.post("/api/v1/robots/robot/control/take")).status_code == 200
        written = await operator.patch(
            "/api/v1/robots/robot/command",
            json={"analog_output_type": {"1": 1}, "analog_output": {"1": 5.0}},
        )
        assert written.status_code == 200, written.text
        switched = await operator.patch(
            "/api/v1/robots/robot/command", json={"controlbox_do": {"2": True}}
        )
        assert switched.status_code == 200, switched.text
        await hmi.service.store.flush_events()
        events = (await operator.get("/api/v1/events?kind=write&limit=5")).json()
        EventPage.model_validate(events)
        audit = (await operator.get("/api/v1/audit?limit=5")).json()["items"]
        audit_csv = await operator.get("/api/v1/audit?limit=5&format=csv")
    latest, analog = events["items"][0], events["items"][1]
    assert analog["summary"] == "AO 1 type = voltage, AO 1 = 5 V"
    assert analog["values"] == {"analog_output_type.1": 1, "analog_output.1": 5.0}
    assert analog["labels"] == {"analog_output_type.1": "AO 1 type", "analog_output.1": "AO 1"}
    assert latest["summary"] == "DO 3 (gripper close) = on"
    assert latest["tags"] == {"controlbox_do.2": "gripper close"}
    writes = [r for r in audit if r["action"] == "write"]
    assert writes[0]["summary"] == "DO 3 (gripper close) = on"
    assert writes[0]["labels"] == {"controlbox_do.2": "DO 3"}
    assert writes[0]["tags"] == {"controlbox_do.2": "gripper close"}
    assert writes[1]["summary"] == "AO 1 type = voltage, AO 1 = 5 V"
    rows = list(csv.DictReader(io.StringIO(audit_csv.text)))
    assert rows and all(datetime.fromisoformat(r["time"]).utcoffset() is not None for r in rows)
    assert orjson.loads(rows[0]["labels"]) == {"controlbox_do.2": "DO 3"}


@contextlib.asynccontextmanager
async def hello(hmi: Running, token: str) -> AsyncIterator[dict[str, Any]]:
    async with connect(
        hmi.robot_ws_url("robot"), additional_headers={"Authorization": f"Bearer {token}"}
    ) as connection:
        yield orjson.loads(await connection.recv())


async def test_control_belongs_to_a_session_not_a_user(hmi: Running) -> None:
    first, second = await hmi.login(OPERATOR), await hmi.login(OPERATOR)  # two windows
    async with hmi.client(first) as window1, hmi.client(second) as window2:
        taken = await window1.post("/api/v1/robots/robot/control/take")
        assert taken.status_code == 200
        assert taken.json()["holder"]["session_is_yours"] is True
        # (The holder's own stream stays open: closing its last one would release control.)
        async with hello(hmi, first) as greeting:
            assert greeting["session"] == greeting["control"]["holder"]["session"]
            assert greeting["control"]["holder"]["session_is_yours"] is True
            await _second_window(hmi, window1, window2, second)
    async with hmi.client() as anonymous_client:
        anonymous = (await anonymous_client.get("/api/v1/robots/robot/status")).json()
    assert anonymous["control"]["holder"] is None  # released with the holder's last stream


async def _second_window(
    hmi: Running, window1: httpx.AsyncClient, window2: httpx.AsyncClient, second: str
) -> None:
    mine = (await window1.get("/api/v1/robots/robot/status")).json()
    theirs = (await window2.get("/api/v1/robots/robot/status")).json()
    RobotStatus.model_validate(theirs)
    assert mine["control"]["holder"]["session_is_yours"] is True
    assert theirs["control"]["holder"]["session_is_yours"] is False
    assert theirs["control"]["holder"]["user"] == OPERATOR[0]
    summary = (await window2.get("/api/v1/robots/robot")).json()
    assert summary["holder"]["session_is_yours"] is False
    async with hello(hmi, second) as greeting:
        holder = greeting["control"]["holder"]
        assert holder["session_is_yours"] is False
        assert greeting["session"] is not None and greeting["session"] != holder["session"]
    # The second window may neither write nor release nor take.
    write = await window2.patch("/api/v1/robots/robot/command", json={"tool_do": {"0": True}})
    assert write.status_code == 409
    assert "another session" in write.json()["detail"]["reason"]
    [refused] = (await window2.get("/api/v1/audit?limit=1")).json()["items"]
    assert (refused["outcome"], refused["summary"]) == ("refused", "Tool DO 1 = on")
    release = await window2.post("/api/v1/robots/robot/control/release")
    assert release.status_code == 409
    assert "another session" in release.json()["detail"]["reason"]
    take = await window2.post("/api/v1/robots/robot/control/take")
    assert take.status_code == 409
    still = (await window1.get("/api/v1/robots/robot/status")).json()
    assert still["control"]["holder"]["session_is_yours"] is True
    ok = await window1.patch("/api/v1/robots/robot/command", json={"tool_do": {"0": True}})
    assert ok.status_code == 200, ok.text
    async with hmi.client() as anonymous_client:
        anonymous = (await anonymous_client.get("/api/v1/robots/robot/status")).json()
    assert anonymous["control"]["holder"]["session_is_yours"] is None

"""Issue 24, the backend of "panel and kiosk as the cell uses them", against a cell of two robots
(the simulated robot behind the real EtherNet/IP target, its control API driving the stops; a
robot standing still beside it) and the service on loopback:

- one emergency stop and its reset ask for one acknowledgement: SAFE_OFF after it is its
  consequence, suppressed by design and named after it; the texts name states in words;
- "acknowledge all shown" in one request, one audited action per alarm, refusals audited per
  alarm too;
- every robot's alarms at a glance (``GET /api/v1/alarms/summary``, anonymous; the stream's
  status of the OTHER robot; ``GET /api/v1/robots`` with frame age and gaps);
- the API's answers above 1 kB gzipped for a client that asks (not with ``gzip;q=0``), a
  streamed CSV export too, WebSockets untouched.

One cell for the module (its tests run in order, each leaving every alarm acknowledged).
"""

from __future__ import annotations

import asyncio
import contextlib
import csv
import gzip
import io
import time
from collections.abc import AsyncIterator, Callable
from typing import Any

import httpx
import orjson
import pytest
import pytest_asyncio
from websockets.asyncio.client import connect

from cobot_hmi.service.api import models
from cobot_hmi.service.api.models import STREAM_MESSAGE
from conftest import _next_host as next_host
from emulator_harness import Emulator, running_emulator
from service_support import (
    OPERATOR,
    VIEWER,
    Running,
    cell_settings,
    emulator,
    eventually,
    running_service,
)

pytestmark = pytest.mark.timeout(240)
SHARED = pytest.mark.asyncio(loop_scope="module")
Cell = tuple[Running, Emulator]

LEFT, RIGHT = "left", "right"
ESTOP = f"{LEFT}:emergency_stop"
DOOR = {"name": "door", "field": "controlbox_di", "index": 2, "active_when": True}


@pytest_asyncio.fixture(scope="module", loop_scope="module")
async def cell(tmp_path_factory: pytest.TempPathFactory) -> AsyncIterator[Cell]:
    plc_host = next_host()
    async with (
        running_emulator(next_host(), plc_host) as left,
        emulator(next_host()) as right,
    ):
        settings = cell_settings(
            [
                (LEFT, left.target.settings.host, left.target.tcp_port),
                (RIGHT, right.settings.host, right.tcp_port),
            ],
            plc_host,
            tmp_path_factory.mktemp("cell"),
            # A connection slow to come up on a busy machine must not add an alarm here.
            alarm_connection_delay_s=600,
            alarms=[{**DOOR, "robot": LEFT}],
            history_flush_s=0.2,
        )
        async with running_service(settings) as hmi:
            await eventually(lambda: state_is(hmi, 14))  # the program runs: STANDALONE_RUNNING
            yield hmi, left


def state_is(hmi: Running, value: int) -> bool:
    latest = hmi.service.robots[LEFT].frames.latest
    return latest is not None and latest[2].robot_state == value


def alarm_state(hmi: Running, alarm_id: str) -> str:
    return str(hmi.service.robots[LEFT].alarms.find(alarm_id).status.state.value)


def valid(model: type[Any], data: Any) -> Any:
    model.model_validate(data)
    return data


async def audit_rows(client: httpx.AsyncClient, after_id: int) -> list[dict[str, Any]]:
    """Audit rows newer than ``after_id``, oldest first."""
    page = valid(models.AuditPage, (await client.get("/api/v1/audit?limit=100")).json())
    return [row for row in reversed(page["items"]) if row["id"] > after_id]


async def newest_audit_id(client: httpx.AsyncClient) -> int:
    items = (await client.get("/api/v1/audit?limit=1")).json()["items"]
    return int(items[0]["id"]) if items else 0


@contextlib.asynccontextmanager
async def stream(url: str) -> AsyncIterator[list[dict[str, Any]]]:
    """Every message of a stream, each valid by the contract, while the block runs."""
    messages: list[dict[str, Any]] = []
    async with connect(url) as connection:

        async def read() -> None:
            async for text in connection:
                message = orjson.loads(text)
                STREAM_MESSAGE.validate_python(message)
                messages.append(message)

        task = asyncio.create_task(read())
        try:
            yield messages
        finally:
            await connection.close()
            with contextlib.suppress(asyncio.CancelledError):
                await asyncio.wait_for(task, 5)


def status_naming(messages: list[dict[str, Any]], check: Callable[[Any], bool]) -> bool:
    return any(m["type"] == "status" and check(m["cell_alarms"]) for m in messages)


@SHARED
async def test_robot_list_carries_frame_age_gaps_and_alarms(cell: Cell) -> None:
    hmi, _ = cell
    await eventually(
        lambda: all(r.alarms.gaps_total is not None for r in hmi.service.robots.values())
    )
    async with hmi.client() as anonymous:  # reading is open: no login
        listing = valid(models.RobotList, (await anonymous.get("/api/v1/robots")).json())
    for robot in listing["robots"]:
        assert robot["stale"] is False
        assert 0.0 <= robot["frame_age_s"] < 60.0
        assert robot["gaps"] == 0 and robot["packet_loss_high"] is False
        alarms = robot["alarms"]
        assert alarms["robot"] == robot["name"]
        assert set(alarms["by_priority"]) == {"critical", "high", "medium", "low", "advisory"}
        assert alarms["annunciated"] == 0 and alarms["top"] is None


@SHARED
async def test_estop_then_reset_asks_for_one_acknowledgement(cell: Cell) -> None:
    hmi, left = cell
    operator = await hmi.login(OPERATOR)
    async with (
        stream(hmi.robot_ws_url(RIGHT)) as right_stream,
        hmi.client() as anonymous,
        hmi.client(operator) as client,
    ):
        before = await newest_audit_id(client)
        await left.post("/estop")
        await eventually(lambda: alarm_state(hmi, ESTOP) == "active_unacknowledged")

        # Every robot's alarms at a glance, anonymously; the cell's most urgent names its robot.
        summary = valid(
            models.CellAlarmSummary, (await anonymous.get("/api/v1/alarms/summary")).json()
        )
        robots = {r["robot"]: r for r in summary["robots"]}
        assert list(robots) == [LEFT, RIGHT]
        assert robots[LEFT]["annunciated"] == 1 and robots[RIGHT]["annunciated"] == 0
        assert robots[LEFT]["by_priority"]["critical"] == {
            "annunciated": 1,
            "active": 1,
            "unacknowledged": 1,
        }
        top = summary["top"]
        assert (top["robot"], top["name"], top["priority"]) == (LEFT, "Emergency stop", "critical")
        assert top["message"] == "robot state Emergency stop, Emergency stopped flag set"
        # A panel open on the OTHER robot hears of it in its stream's status.
        await eventually(
            lambda: status_naming(
                right_stream, lambda c: c["top"] is not None and c["top"]["id"] == ESTOP
            )
        )
        hello = right_stream[0]
        assert hello["type"] == "hello" and hello["cell_alarms"]["robots"][1]["robot"] == RIGHT

        # The reset: the e-stop returns (unacknowledged), SAFE_OFF passes as its consequence.
        await left.post("/reset")
        await eventually(lambda: state_is(hmi, 13))  # STANDALONE_STANDBY
        safe_off = hmi.service.robots[LEFT].alarms.find(f"{LEFT}:safe_off").status
        await eventually(lambda: safe_off.state == "normal" and safe_off.cleared_at is not None)
        current = valid(models.AlarmList, (await anonymous.get("/api/v1/alarms")).json())
        assert [(a["id"], a["state"]) for a in current["items"]] == [
            (ESTOP, "returned_unacknowledged")
        ]
        assert current["items"][0]["message"] == "robot state now Safe off (servo off)"
        everything = (await anonymous.get(f"/api/v1/alarms?robot={LEFT}&which=all")).json()
        consequence = next(a for a in everything["items"] if a["key"] == "safe_off")
        assert consequence["suppressed_by"] == ESTOP
        assert consequence["suppressed_by_name"] == "Emergency stop"
        await hmi.service.robots[LEFT].alarm_store.flush()
        history = valid(
            models.AlarmHistoryPage,
            (await anonymous.get(f"/api/v1/alarms/history?robot={LEFT}")).json(),
        )
        rows = [
            (r["key"], r["transition"], r["state"], r["suppressed_by"], r["message"])
            for r in reversed(history["items"])
            if r["key"] in ("emergency_stop", "safe_off")
        ]
        assert rows[-3:] == [
            (
                "emergency_stop",
                "cleared",
                "returned_unacknowledged",
                None,
                "robot state now Safe off (servo off)",
            ),
            ("safe_off", "activated", "suppressed", ESTOP, "robot state Safe off (servo off)"),
            ("safe_off", "cleared", "normal", None, "robot state now Standalone standby"),
        ]

        # The events in words: the log, and its CSV.
        await hmi.service.store.flush_events()
        events = valid(
            models.EventPage, (await client.get(f"/api/v1/events?robot={LEFT}&limit=200")).json()
        )
        texts = [e["text"] for e in reversed(events["items"])]
        assert "Servo on flag cleared" in texts
        assert "Robot state Emergency stop (was Standalone running)" in texts
        assert (
            "Servo off after an error (SAFE_OFF) activated, suppressed by design (a consequence "
            "of Emergency stop): robot state Safe off (servo off)"
        ) in texts
        assert not [t for t in texts if " on on" in t or "robot state 2" in t]
        csv_rows = list(
            csv.DictReader(io.StringIO((await client.get("/api/v1/events?format=csv")).text))
        )
        assert "Servo on flag cleared" in [row["text"] for row in csv_rows]

        # Acknowledge all shown: the one alarm there is, one audited action.
        answer = await client.post(
            "/api/v1/alarms/ack", json={"robot": LEFT, "comment": "cell checked"}
        )
        assert answer.status_code == 200, answer.text
        body = valid(models.AlarmAckManyAnswer, answer.json())
        assert [(i["id"], i["outcome"]) for i in body["items"]] == [(ESTOP, "acknowledged")]
        assert body["acknowledged"] == 1 and body["items"][0]["alarm"]["state"] == "normal"
        acks = [r for r in await audit_rows(client, before) if r["action"] == "alarm.ack"]
        assert [(r["fields"], r["outcome"], r["origin"]) for r in acks] == [
            (["emergency_stop"], "acknowledged", "POST /api/v1/alarms/ack")
        ]
        assert acks[0]["summary"] == "Emergency stop: acknowledged — cell checked"
        again = (await anonymous.get("/api/v1/alarms/summary")).json()
        assert again["annunciated"] == 0 and again["top"] is None


@SHARED
async def test_acknowledging_many_is_one_audited_action_per_alarm(cell: Cell) -> None:
    hmi, left = cell
    door, stop = f"{LEFT}:user.door", f"{LEFT}:protective_stop"
    normal = [f"{LEFT}:motor_temperature.0", f"{LEFT}:safe_off"]
    operator, viewer = await hmi.login(OPERATOR), await hmi.login(VIEWER)
    async with (
        hmi.client(operator) as client,
        hmi.client(viewer) as viewing,
        hmi.client() as anonymous,
    ):
        # Two alarms to acknowledge: the cell door (a user alarm on DI 3) and a protective stop
        # that came and went (its reset's SAFE_OFF is its consequence).
        await left.post("/inputs", {"controlbox_di": {"2": True}})
        await left.post("/protective-stop")
        await eventually(lambda: alarm_state(hmi, stop) == "active_unacknowledged")
        await left.post("/reset")
        await eventually(lambda: alarm_state(hmi, stop) == "returned_unacknowledged")
        await eventually(lambda: alarm_state(hmi, door) == "active_unacknowledged")
        await eventually(lambda: state_is(hmi, 13) and alarm_state(hmi, normal[1]) == "normal")
        before = await newest_audit_id(client)

        # An unknown alarm: nothing acknowledged, nothing audited.
        missing = await client.post("/api/v1/alarms/ack", json={"ids": [stop, f"{LEFT}:nope"]})
        assert missing.status_code == 404 and missing.json()["detail"]["field"] == "alarm_id"
        malformed: list[dict[str, object]] = [{}, {"ids": [stop], "robot": LEFT}, {"ids": []}]
        for body in malformed:
            assert (await client.post("/api/v1/alarms/ack", json=body)).status_code == 422, body
        assert await audit_rows(client, before) == []

        # Refused by role: one audited refusal per alarm asked. (Without a login the request
        # ends before any route, as every change does: counted in /metrics, not audited.)
        assert (
            await viewing.post("/api/v1/alarms/ack", json={"ids": [stop, door]})
        ).status_code == 403
        assert (
            await anonymous.post("/api/v1/alarms/ack", json={"ids": [stop, door]})
        ).status_code == 401
        refusals = await audit_rows(client, before)
        assert [(r["user"], r["fields"], r["outcome"]) for r in refusals] == [
            (VIEWER[0], ["protective_stop"], "forbidden"),
            (VIEWER[0], ["user.door"], "forbidden"),
        ]
        assert alarm_state(hmi, stop) == "returned_unacknowledged"

        # Granted: each alarm acknowledged (or refused: normal) and audited on its own.
        middle = await newest_audit_id(client)
        answer = await client.post(
            "/api/v1/alarms/ack", json={"ids": [stop, door, *normal], "comment": "seen"}
        )
        assert answer.status_code == 200, answer.text
        body = valid(models.AlarmAckManyAnswer, answer.json())
        assert [(i["id"], i["outcome"]) for i in body["items"]] == [
            (stop, "acknowledged"),
            (door, "acknowledged"),
            (normal[0], "refused"),
            (normal[1], "refused"),
        ]
        assert body["acknowledged"] == 2
        assert "nothing to acknowledge" in body["items"][2]["reason"]
        rows = await audit_rows(client, middle)
        assert [(r["user"], r["fields"], r["outcome"], r["requested"]) for r in rows] == [
            (OPERATOR[0], ["protective_stop"], "acknowledged", {"comment": "seen"}),
            (OPERATOR[0], ["user.door"], "acknowledged", {"comment": "seen"}),
            (OPERATOR[0], ["motor_temperature.0"], "refused", {"comment": "seen"}),
            (OPERATOR[0], ["safe_off"], "refused", {"comment": "seen"}),
        ]
        assert alarm_state(hmi, stop) == "normal"
        assert alarm_state(hmi, door) == "active_acknowledged"
        await left.post("/inputs", {"controlbox_di": {"2": False}})
        await eventually(lambda: alarm_state(hmi, door) == "normal")


async def raw_get(
    client: httpx.AsyncClient, path: str, accept: str, **params: Any
) -> tuple[httpx.Response, bytes]:
    """The answer's bytes as they came over the wire (httpx would decode them)."""
    headers = {"Accept-Encoding": accept}
    async with client.stream("GET", path, headers=headers, params=params) as answer:
        body = b"".join([chunk async for chunk in answer.aiter_raw()])
    return answer, body


@SHARED
async def test_answers_above_1kb_are_gzipped_for_a_client_that_asks(cell: Cell) -> None:
    hmi, _ = cell
    async with hmi.client() as client:
        plain, plain_body = await raw_get(client, f"/api/v1/robots/{LEFT}/tags", "identity")
        assert "content-encoding" not in plain.headers
        assert len(plain_body) > 10_000
        packed, packed_body = await raw_get(client, f"/api/v1/robots/{LEFT}/tags", "gzip")
        assert packed.headers["content-encoding"] == "gzip"
        assert "Accept-Encoding" in packed.headers["vary"]
        assert packed.headers["content-type"] == "application/json"
        assert len(packed_body) < len(plain_body) // 4
        assert orjson.loads(gzip.decompress(packed_body)) == orjson.loads(plain_body)
        # Security headers are still there (the compression sits inside those middlewares).
        assert packed.headers["x-content-type-options"] == "nosniff"
        # A weight of 0 refuses gzip; a short answer is not worth it.
        refused, _ = await raw_get(client, f"/api/v1/robots/{LEFT}/tags", "br, gzip;q=0")
        assert "content-encoding" not in refused.headers
        short, short_body = await raw_get(client, "/healthz", "gzip")
        assert "content-encoding" not in short.headers and len(short_body) < 1000

        # A streamed CSV export, chunk by chunk; Parquet (zstd inside) as it is.
        status: dict[str, Any] = {}
        deadline = time.monotonic() + 30
        while not status.get("last") or status["last"] - status["first"] < 1.0:
            assert time.monotonic() < deadline, status
            status = (await client.get(f"/api/v1/robots/{LEFT}/history/status")).json()
            await asyncio.sleep(0.1)
        span = {"from": status["first"], "to": status["last"], "fields": "joint_position"}
        exported, exported_body = await raw_get(
            client, f"/api/v1/robots/{LEFT}/export", "gzip", format="csv", **span
        )
        assert exported.status_code == 200
        assert exported.headers["content-encoding"] == "gzip"
        text = gzip.decompress(exported_body).decode()
        assert text.startswith('"time","seq","t2o_sequence","joint_position.J1 [degree]",')
        assert text.count("\n") > 10
        parquet, parquet_body = await raw_get(
            client, f"/api/v1/robots/{LEFT}/export", "gzip", format="parquet", **span
        )
        assert "content-encoding" not in parquet.headers
        assert parquet_body.startswith(b"PAR1")
    # The stream (a WebSocket, through the same middlewares) is untouched.
    async with stream(hmi.robot_ws_url(LEFT)) as messages:
        await eventually(lambda: any(m["type"] == "frames" for m in messages))
    assert messages[0]["type"] == "hello"

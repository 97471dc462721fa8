"""The per-robot API against two emulated robots and the real service on loopback: the robot
list, per-robot reads, writes and control that stay with their robot, the deprecated
single-robot paths answering for the first robot, 404s naming the known robots, per-robot
events, audit and metrics, malformed write bodies answered 422 naming the field and audited,
and every answer checked against its model in the contract."""

from __future__ import annotations

import asyncio
import contextlib
import re
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import httpx
import hypothesis
import orjson
import pytest
import pytest_asyncio
from hypothesis import strategies as st
from prometheus_client.parser import text_string_to_metric_families
from pydantic import BaseModel
from websockets.asyncio.client import connect
from websockets.exceptions import ConnectionClosed

from cobot_hmi.emulator.static_robot import StaticRobot
from cobot_hmi.emulator.target import Target
from cobot_hmi.service.api import models
from cobot_hmi.service.writes.pipeline import Writer, submit_write, take_control
from conftest import _next_host as next_host
from service_support import (
    OPERATOR,
    OPERATOR_2,
    Running,
    cell_settings,
    emulator,
    eventually,
    running_service,
)

pytestmark = pytest.mark.timeout(180)

JSON = {"Content-Type": "application/json"}


@pytest.fixture
def left_robot() -> StaticRobot:
    return StaticRobot()


@pytest.fixture
def right_robot() -> StaticRobot:
    return StaticRobot()


Cell = tuple[Running, Target, Target]


@contextlib.asynccontextmanager
async def two_robot_cell(
    plc_host: str, state_dir: Path, left_robot: StaticRobot, right_robot: StaticRobot
) -> AsyncIterator[Cell]:
    async with (
        emulator(next_host(), left_robot) as left,
        emulator(next_host(), right_robot) as right,
    ):
        settings = cell_settings(
            [
                ("left", left.settings.host, left.tcp_port),
                ("right", right.settings.host, right.tcp_port),
            ],
            plc_host,
            state_dir,
            # No test here is about the confirmation timeout: a busy machine must not fail one.
            write_timeout_ms=10_000.0,
        )
        async with running_service(settings) as running:
            yield running, left, right


@pytest.fixture
async def cell(
    plc_host: str, tmp_path: Path, left_robot: StaticRobot, right_robot: StaticRobot
) -> AsyncIterator[Cell]:
    """A cell of the test's own: for the tests that take control or write."""
    async with two_robot_cell(plc_host, tmp_path, left_robot, right_robot) as running:
        yield running


@pytest_asyncio.fixture(scope="module", loop_scope="module")
async def shared_robots() -> tuple[StaticRobot, StaticRobot]:
    return StaticRobot(), StaticRobot()


@pytest_asyncio.fixture(scope="module", loop_scope="module")
async def shared_cell(
    tmp_path_factory: pytest.TempPathFactory, shared_robots: tuple[StaticRobot, StaticRobot]
) -> AsyncIterator[Cell]:
    """One cell for the module's tests that only read, or whose every write is refused and
    leaves the robots' command images as they were (each releases what it takes)."""
    state_dir = tmp_path_factory.mktemp("shared-cell")
    async with two_robot_cell(next_host(), state_dir, *shared_robots) as running:
        yield running


SHARED = pytest.mark.asyncio(loop_scope="module")
"""The tests on ``shared_cell`` run in the module's event loop, where it runs."""


def _valid(model: type[BaseModel], data: Any) -> Any:
    model.model_validate(data)
    return data


@SHARED
async def test_robot_list_and_per_robot_reads(shared_cell: Cell) -> None:
    hmi, left, right = shared_cell
    async with hmi.client() as client:
        listing = _valid(models.RobotList, (await client.get("/api/v1/robots")).json())
        robots = {r["name"]: r for r in listing["robots"]}
        assert list(robots) == ["left", "right"]
        assert robots["left"]["host"] == left.settings.host and robots["left"]["default"]
        assert robots["right"]["host"] == right.settings.host and not robots["right"]["default"]
        for robot in robots.values():
            assert robot["connection"] == "connected"
            assert robot["mode"] == "exclusive_owner"
            assert robot["holder"] is None
            assert robot["robot_state_name"] == "STANDALONE_STANDBY"
        await eventually(lambda: all(r.identity is not None for r in hmi.service.robots.values()))
        one = _valid(models.RobotSummary, (await client.get("/api/v1/robots/right")).json())
        assert one["model"] and one["identity"]["product_name"] == one["model"]
        for name in ("left", "right"):
            frame = _valid(
                models.FrameAnswer, (await client.get(f"/api/v1/robots/{name}/frame")).json()
            )
            assert frame["robot"] == name and frame["stale"] is False
            status = _valid(
                models.RobotStatus, (await client.get(f"/api/v1/robots/{name}/status")).json()
            )
            host = left.settings.host if name == "left" else right.settings.host
            assert status["connection"]["robot"] == host
            command = _valid(
                models.CommandState, (await client.get(f"/api/v1/robots/{name}/command")).json()
            )
            assert command["robot"] == name and command["run"] is False
            ready = await client.get(f"/api/v1/robots/{name}/readyz")
            assert _valid(models.Ready, ready.json()) == {
                "ready": True,
                "reason": None,
                "robot": name,
            }
        assert (await client.get("/readyz?robot=right")).json()["robot"] == "right"
        health = _valid(models.Health, (await client.get("/healthz")).json())
        assert health == {"ok": True, "problems": []}
        layout = (await client.get("/api/v1/layout")).json()
        models.LayoutDocument.model_validate(layout)


@SHARED
async def test_unknown_robot_is_a_404_naming_the_known_ones(shared_cell: Cell) -> None:
    hmi, _, _ = shared_cell
    audited = (await hmi.service.store.audit_page(10, 0)).total
    token = await hmi.login(OPERATOR)
    async with hmi.client(token) as client:
        for method, path in (
            ("GET", "/api/v1/robots/nope"),
            ("GET", "/api/v1/robots/nope/frame"),
            ("GET", "/api/v1/robots/nope/status"),
            ("GET", "/api/v1/robots/nope/command"),
            ("GET", "/api/v1/robots/nope/readyz"),
            ("PATCH", "/api/v1/robots/nope/command"),
            ("POST", "/api/v1/robots/nope/control/take"),
            ("POST", "/api/v1/robots/nope/control/release"),
            ("GET", "/api/v1/robots/NOT%20A%20NAME/frame"),
        ):
            body = b'{"tool_do": {"0": true}}' if method == "PATCH" else None
            answer = await client.request(method, path, content=body, headers=JSON)
            assert answer.status_code == 404, (method, path)
            detail = _valid(models.ApiErrorResponse, answer.json())["detail"]
            assert detail["field"] == "name"
            assert detail["known"] == ["left", "right"]
            assert "known: left, right" in detail["reason"]
        for path in ("/api/v1/audit?robot=nope", "/api/v1/events?robot=nope", "/readyz?robot=x"):
            answer = await client.get(path)
            assert answer.status_code == 404, path
            assert answer.json()["detail"]["field"] == "robot"
            assert answer.json()["detail"]["known"] == ["left", "right"]
    with pytest.raises(ConnectionClosed) as closed:
        async with connect(hmi.robot_ws_url("nope")) as stream:
            await stream.recv()
    assert closed.value.rcvd is not None
    assert closed.value.rcvd.code == 4404
    assert "known: left, right" in closed.value.rcvd.reason
    # Nothing of it reached the audit trail: nobody wrote to a robot.
    assert (await hmi.service.store.audit_page(10, 0)).total == audited


async def test_control_and_writes_stay_with_their_robot(
    cell: tuple[Running, Target, Target], left_robot: StaticRobot, right_robot: StaticRobot
) -> None:
    hmi, _, _ = cell
    olivia, oscar = await hmi.login(OPERATOR), await hmi.login(OPERATOR_2)
    async with hmi.client(olivia) as left_op, hmi.client(oscar) as right_op:
        take = await left_op.post("/api/v1/robots/left/control/take")
        assert _valid(models.ControlStatus, take.json())["holder"]["user"] == OPERATOR[0]
        # Control of one robot says nothing about the other.
        take = await right_op.post("/api/v1/robots/right/control/take")
        assert take.status_code == 200, take.text
        refused = await left_op.patch(
            "/api/v1/robots/right/command", json={"controlbox_do": {"2": True}}
        )
        assert refused.status_code == 409
        assert OPERATOR_2[0] in refused.json()["detail"]["reason"]
        write = await left_op.patch(
            "/api/v1/robots/left/command", json={"controlbox_do": {"2": True}}
        )
        assert write.status_code == 200, write.text
        confirmed = _valid(models.WriteConfirmed, write.json())
        assert confirmed["image"]["controlbox_do"][2] is True
        write = await right_op.patch("/api/v1/robots/right/command", json={"tool_do": {"0": True}})
        assert write.status_code == 200, write.text
        # Index 2 is DO 3 on the left robot only; Tool DO 1 on the right one only.
        assert left_robot.command_image().controlbox_do[2] is True
        assert left_robot.command_image().tool_do[0] is False
        assert right_robot.command_image().tool_do[0] is True
        assert right_robot.command_image().controlbox_do[2] is False
        robots = {r["name"]: r for r in (await left_op.get("/api/v1/robots")).json()["robots"]}
        assert robots["left"]["holder"]["user"] == OPERATOR[0]
        assert robots["right"]["holder"]["user"] == OPERATOR_2[0]
        release = await right_op.post("/api/v1/robots/right/control/release")
        assert release.json() == {"holder": None}
        assert hmi.service.robot("left").control.holder is not None

        # Per-robot audit: rows carry the robot's name and the door; ?robot= filters.
        audit = (await left_op.get("/api/v1/audit?robot=right")).json()
        _valid(models.AuditPage, audit)
        assert {row["robot"] for row in audit["items"]} == {"right"}
        actions = [(row["action"], row["outcome"]) for row in audit["items"]]
        assert actions == [
            ("control.release", "released"),
            ("write", "confirmed"),
            ("write", "refused"),  # olivia's, while oscar held the right robot
            ("control.take", "granted"),
        ]
        assert audit["items"][2]["user"] == OPERATOR[0]
        left_rows = (await left_op.get("/api/v1/audit?robot=left")).json()["items"]
        assert [(r["action"], r["outcome"]) for r in left_rows] == [
            ("write", "confirmed"),
            ("control.take", "granted"),
        ]
        assert left_rows[0]["origin"] == "PATCH /api/v1/robots/left/command"
        assert left_rows[0]["fields"] == ["controlbox_do.2"]
        everything = (await left_op.get("/api/v1/audit")).json()
        assert everything["total"] == 6

        # Per-robot events.
        await hmi.service.store.flush_events()
        events = (await left_op.get("/api/v1/events?robot=right&limit=1000")).json()
        _valid(models.EventPage, events)
        assert {e["robot"] for e in events["items"]} == {"right"}
        kinds = {e["kind"] for e in events["items"]}
        assert {"connection", "robot_state", "control", "write"} <= kinds
        writes = (await left_op.get("/api/v1/events?kind=write&robot=left")).json()["items"]
        assert [w["fields"] for w in writes] == [["controlbox_do.2"]]
        csv_text = (await left_op.get("/api/v1/events?robot=left&format=csv")).text
        assert csv_text.splitlines()[0] == "id,time,robot,kind,text,data"

    # Per-robot metrics.
    metrics = await hmi.metrics()
    for name in ("left", "right"):
        assert f'cobot_hmi_connection_state{{robot="{name}",state="connected"}} 1.0' in metrics
        assert f'cobot_hmi_writes_total{{outcome="confirmed",robot="{name}"}} 1.0' in metrics
    assert 'cobot_hmi_writes_total{outcome="refused",robot="right"} 1.0' in metrics
    assert 'cobot_hmi_control_held{robot="left"} 1.0' in metrics
    assert 'cobot_hmi_control_held{robot="right"} 0.0' in metrics
    # Each metric's HELP and TYPE once, before every robot's samples.
    assert metrics.count("# TYPE cobot_hmi_frames_received_total counter") == 1


async def test_deprecated_single_robot_paths_answer_for_the_first_robot(
    cell: tuple[Running, Target, Target], left_robot: StaticRobot, right_robot: StaticRobot
) -> None:
    hmi, left, _ = cell
    async with hmi.client(await hmi.login(OPERATOR)) as client:
        frame = (await client.get("/api/v1/frame")).json()
        assert frame["robot"] == "left"
        status = (await client.get("/api/v1/status")).json()
        assert status["connection"]["robot"] == left.settings.host
        assert (await client.get("/api/v1/command")).json()["robot"] == "left"
        assert (await client.post("/api/v1/control/take")).status_code == 200
        write = await client.patch("/api/v1/command", json={"controlbox_do": {"5": True}})
        assert write.status_code == 200, write.text
        assert left_robot.command_image().controlbox_do[5] is True
        assert right_robot.command_image().controlbox_do[5] is False
        assert hmi.service.robot("left").control.holder is not None
        assert hmi.service.robot("right").control.holder is None
        assert (await client.post("/api/v1/control/release")).json() == {"holder": None}
        row = (await client.get("/api/v1/audit?limit=2")).json()["items"][1]
        assert row["robot"] == "left" and row["origin"] == "PATCH /api/v1/command"
    async with connect(hmi.ws_url) as stream:
        hello = orjson.loads(await stream.recv())
    assert models.HelloMessage.model_validate(hello).robot == "left"


@pytest.mark.parametrize(
    ("body", "field"),
    [
        (b'{"extra": "00"}', "extra"),  # a frame-only key: a 500 before
        ('{"controlbox_do": {"²": true}}'.encode(), "controlbox_do"),  # a 500 before
        (b'{"controlbox_do": {"03": true}}', "controlbox_do"),  # not canonical decimal
        ('{"controlbox_do": {"٣": true}}'.encode(), "controlbox_do"),  # another script's 3
        (b'{"controlbox_do": {"16": true}}', "controlbox_do.16"),
        (b'{"controlbox_do": true}', "controlbox_do"),
        (b'{"analog_output": {"0": 1e400}}', None),  # not JSON orjson reads (inf)
        (b'{"robot_state_name": "X"}', "robot_state_name"),
        (b"[]", None),
        (b"{}", None),
        (b"null", None),
        (b"{", None),
    ],
)
@SHARED
async def test_malformed_write_bodies_are_422_naming_the_field_and_audited(
    shared_cell: Cell,
    shared_robots: tuple[StaticRobot, StaticRobot],
    body: bytes,
    field: str | None,
) -> None:
    hmi, _, _ = shared_cell
    right_robot = shared_robots[1]
    invalid_before = _invalid_writes(await hmi.metrics(), "right")
    async with hmi.client(await hmi.login(OPERATOR)) as client:
        assert (await client.post("/api/v1/robots/right/control/take")).status_code == 200
        before = (await client.get("/api/v1/robots/right/command")).json()["image"]
        answer = await client.patch("/api/v1/robots/right/command", content=body, headers=JSON)
        assert answer.status_code == 422, answer.text
        detail = _valid(models.ApiErrorResponse, answer.json())["detail"]
        assert detail["field"] == field
        assert detail["reason"]
        # Nothing applied.
        assert (await client.get("/api/v1/robots/right/command")).json()["image"] == before
        assert right_robot.command_image().controlbox_do[3] is False
        rows = (await client.get("/api/v1/audit?robot=right&limit=1")).json()["items"]
        assert (await client.post("/api/v1/robots/right/control/release")).status_code == 200
    _valid(models.AuditPage, {"items": rows, "total": 1})
    (row,) = rows  # the newest
    assert (row["action"], row["outcome"], row["user"]) == ("write", "invalid", OPERATOR[0])
    assert row["reason"] == detail["reason"]
    assert row["origin"] == "PATCH /api/v1/robots/right/command"
    metrics = await hmi.metrics()
    assert _invalid_writes(metrics, "right") == invalid_before + 1
    assert _invalid_writes(metrics, "left") == 0  # nobody writes to the left robot here


def _invalid_writes(metrics: str, robot: str) -> float:
    """``cobot_hmi_writes_total{outcome="invalid",robot=ROBOT}`` in a /metrics text."""
    found = re.search(
        rf'cobot_hmi_writes_total\{{outcome="invalid",robot="{robot}"\}} (\S+)', metrics
    )
    assert found is not None, metrics
    return float(found[1])


@SHARED
async def test_the_cyclic_pump_counts_every_robots_packets(shared_cell: Cell) -> None:
    """The one UDP 2222 socket's pump (``cyclic_pump_*``): what it read is at least every
    robot's frames counted before it (the pump reads a datagram before its originator sees it)
    and at most what both emulators sent to it (read after the scrape; only they send to this
    service's address)."""
    hmi, left, right = shared_cell
    robots = hmi.service.robots.values()
    await eventually(lambda: all(r.intervals.frames_in > 0 for r in robots))
    families = {f.name: f for f in text_string_to_metric_families(await hmi.metrics())}
    sent_by_emulators = sum(e.pump_counters()["sent"] for e in (left, right))

    def value(name: str) -> float:
        (sample,) = families[name].samples
        return sample.value

    frames = sum(s.value for s in families["cobot_hmi_frames_received"].samples)
    received = value("cobot_hmi_cyclic_pump_datagrams_received")
    assert frames > 0
    assert frames <= received <= sent_by_emulators
    assert value("cobot_hmi_cyclic_pump_datagrams_sent") > 0
    assert value("cobot_hmi_cyclic_pump_wakeups") > 0
    assert value("cobot_hmi_cyclic_pump_realtime") in (0, 1)
    assert 0 <= value("cobot_hmi_cyclic_pump_send_late_max_seconds") < 3600
    for counter in ("send_errors", "ring_overflows"):
        assert families[f"cobot_hmi_cyclic_pump_{counter}"].type == "counter"


async def test_each_robot_streams_its_own_frames_and_events(
    cell: tuple[Running, Target, Target],
) -> None:
    hmi, _, _ = cell
    token = await hmi.login(OPERATOR)
    messages: dict[str, list[Any]] = {"left": [], "right": []}
    async with (
        connect(hmi.robot_ws_url("left")) as left_stream,
        connect(hmi.robot_ws_url("right")) as right_stream,
    ):
        for name, stream in (("left", left_stream), ("right", right_stream)):
            messages[name].append(orjson.loads(await stream.recv()))
        async with hmi.client(token) as client:
            assert (await client.post("/api/v1/robots/right/control/take")).status_code == 200
        for name, stream in (("left", left_stream), ("right", right_stream)):
            while not any(m["type"] == "frames" for m in messages[name]) or (
                name == "right" and not any(m["type"] == "event" for m in messages[name])
            ):
                messages[name].append(orjson.loads(await stream.recv()))
    for name, received in messages.items():
        for message in received:
            models.STREAM_MESSAGE.validate_python(message)  # the contract's model
        assert received[0]["type"] == "hello" and received[0]["robot"] == name
        events = [m["event"] for m in received if m["type"] == "event"]
        assert all(e["robot"] == name for e in events)
    right_control = [
        m["event"]
        for m in messages["right"]
        if m["type"] == "event" and m["event"]["kind"] == "control"
    ]
    assert right_control and right_control[0]["holder"]["user"] == OPERATOR[0]
    assert not any(
        m["type"] == "event" and m["event"]["kind"] == "control" for m in messages["left"]
    )


async def test_health_and_readiness_per_robot_with_one_robot_gone(
    robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    ghost_host = next_host()  # nobody answers there: refused every time it is tried
    async with emulator(robot_host) as left:
        settings = cell_settings(
            [("left", robot_host, left.tcp_port), ("ghost", ghost_host, 44818)],
            plc_host,
            tmp_path,
            link_down_unhealthy_s=0.5,
        )
        async with running_service(settings, wait_connected=False) as hmi:
            assert await hmi.service.robot("left").link.wait_connected(30.0)
            async with hmi.client() as client:
                left_ready = await client.get("/api/v1/robots/left/readyz")
                assert left_ready.status_code == 200
                ghost_ready = await client.get("/api/v1/robots/ghost/readyz")
                assert ghost_ready.status_code == 503
                assert _valid(models.Ready, ghost_ready.json())["robot"] == "ghost"
                assert ghost_ready.json()["reason"]
                everyone = await client.get("/readyz")
                assert everyone.status_code == 503 and everyone.json()["robot"] == "ghost"
                assert (await client.get("/readyz?robot=left")).status_code == 200

                async def unhealthy() -> Any:
                    answer = await client.get("/healthz")
                    return answer if answer.status_code == 503 else None

                health = None
                for _ in range(600):  # the bound is 0.5 s; a generous deadline under load
                    health = await unhealthy()
                    if health is not None:
                        break
                    await asyncio.sleep(0.05)
                assert health is not None, "/healthz never reported the robot that is gone"
                body = _valid(models.Health, health.json())
                assert body["ok"] is False
                assert any("ghost" in problem for problem in body["problems"])
                assert not any("left" in problem for problem in body["problems"])
                # The other robot keeps streaming and answering.
                frame = (await client.get("/api/v1/robots/left/frame")).json()
                assert frame["stale"] is False


async def test_a_non_http_writer_goes_through_the_same_pipeline(
    cell: tuple[Running, Target, Target], right_robot: StaticRobot
) -> None:
    """A later door (an MQTT client, a script) calls ``submit_write`` with a parsed body: the
    same authorization, validation, audit, confirmation and outcome as HTTP."""
    hmi, _, _ = cell
    right = hmi.service.robot("right")
    token = await hmi.login(OPERATOR)
    session = hmi.service.sessions.get(token)
    assert session is not None
    script = Writer.from_session(session, "script-7")
    nobody = Writer(None, None, "mqtt-client-1")

    anonymous = await submit_write(right, nobody, {"tool_do": {"0": True}}, origin="mqtt")
    assert (anonymous.status, anonymous.outcome) == (401, "unauthorized")
    invalid = await submit_write(right, script, {"tool_do": {"9": True}}, origin="script")
    assert (invalid.status, invalid.outcome, invalid.field) == (422, "invalid", "tool_do.9")
    not_holding = await submit_write(right, script, {"tool_do": {"0": True}}, origin="script")
    assert (not_holding.status, not_holding.outcome) == (409, "refused")
    assert "/api/v1/robots/right/control/take" in (not_holding.reason or "")
    taken = models.ControlStatus.model_validate(await take_control(right, script, origin="script"))
    assert taken.holder is not None and taken.holder.user == OPERATOR[0]
    done = await submit_write(right, script, {"tool_do": {"0": True}}, origin="script")
    assert done.ok and done.outcome == "confirmed"
    models.WriteConfirmed.model_validate(done.answer())
    assert done.image is not None and done.image["tool_do"] == (True, *[False] * 5)
    assert right_robot.command_image().tool_do[0] is True

    rows = (await hmi.service.store.audit_page(10, 0, robot="right")).items
    assert [(r["action"], r["outcome"], r["client"], r["origin"]) for r in rows] == [
        ("write", "confirmed", "script-7", "script"),
        ("control.take", "granted", "script-7", None),
        ("write", "refused", "script-7", "script"),
        ("write", "invalid", "script-7", "script"),
        ("write", "unauthorized", "mqtt-client-1", "mqtt"),
    ]
    assert rows[3]["requested"] == {"tool_do": {"9": True}}


async def test_writes_generated_from_the_openapi_schema_are_accepted(
    cell: tuple[Running, Target, Target], right_robot: StaticRobot
) -> None:
    """A fuzzer working from ``/openapi.json`` alone produces writes the service takes: every
    body the ``CommandPatch`` schema allows is confirmed, or refused 422 only for what the schema
    cannot say (an analog value outside its type's range, an empty body)."""
    hmi, _, _ = cell
    token = await hmi.login(OPERATOR)
    async with hmi.client(token) as client:
        document = (await client.get("/openapi.json")).json()
        assert (await client.post("/api/v1/robots/right/control/take")).status_code == 200
    schema = document["components"]["schemas"]["CommandPatch"]
    outcomes: list[int] = []

    @hypothesis.settings(
        max_examples=40,
        deadline=None,
        derandomize=True,  # the same bodies every run: no flakes from a lucky draw
        suppress_health_check=[hypothesis.HealthCheck.too_slow],
        database=None,
    )
    @hypothesis.given(_bodies(schema))
    def write(body: dict[str, dict[str, Any]]) -> None:
        with httpx.Client(
            base_url=hmi.base_url, headers={"Authorization": f"Bearer {token}"}, timeout=30.0
        ) as http:
            answer = http.patch("/api/v1/robots/right/command", json=body)
        outcomes.append(answer.status_code)
        if answer.status_code == 422:
            detail = answer.json()["detail"]
            if body:
                assert detail["field"].startswith("analog_output."), (body, detail)
                assert "outside" in detail["reason"], (body, detail)
            else:
                assert detail["field"] is None
            return
        assert answer.status_code == 200, (body, answer.text)
        image = models.WriteConfirmed.model_validate(answer.json()).image
        for name, values in body.items():
            for index, value in values.items():
                written = getattr(image, name)[int(index)]
                assert written == pytest.approx(value), (name, index)

    await asyncio.to_thread(write)  # the service and the emulator keep this event loop
    assert outcomes.count(200) >= len(outcomes) // 2, outcomes
    assert right_robot.command_image() == hmi.service.robot("right").link.command


def _element(schema: dict[str, Any]) -> st.SearchStrategy[Any]:
    """Values one JSON schema of the contract allows (its element types only)."""
    kind = schema["type"]
    if kind == "boolean":
        return st.booleans()
    if kind == "integer":
        return st.integers(schema.get("minimum", -(2**31)), schema.get("maximum", 2**31))
    assert kind == "number", schema
    return st.floats(
        schema.get("minimum"), schema.get("maximum"), allow_nan=False, allow_infinity=False
    )


def _bodies(schema: dict[str, Any]) -> st.SearchStrategy[dict[str, dict[str, Any]]]:
    """Bodies the ``CommandPatch`` schema allows, read from the schema alone: each property an
    object whose keys match its one key pattern and whose values have its element type."""
    assert schema["additionalProperties"] is False
    fields = {}
    for name, field in schema["properties"].items():
        assert field["type"] == "object" and field["additionalProperties"] is False
        ((pattern, element),) = field["patternProperties"].items()
        fields[name] = st.dictionaries(
            st.from_regex(pattern, fullmatch=True), _element(element), max_size=4
        )
    return st.fixed_dictionaries({}, optional=fields)

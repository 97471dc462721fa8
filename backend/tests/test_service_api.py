"""The service's REST API against the emulator over real sockets: reading, login and roles,
control, every write path and refusal, confirmation and its timeout, audit and events, the
frontend at ``/``."""

from __future__ import annotations

import asyncio
import csv
import io
import json
from collections.abc import AsyncIterator
from pathlib import Path

import pytest

from cobot_hmi.emulator.static_robot import StaticRobot
from cobot_hmi.emulator.target import Target
from service_support import (
    ADMIN,
    OPERATOR,
    OPERATOR_2,
    VIEWER,
    Running,
    emulator,
    eventually,
    eventually_async,
    hmi_fixture,
    running_service,
    service_settings,
)

pytestmark = pytest.mark.timeout(120)


@pytest.fixture
def robot() -> StaticRobot:
    return StaticRobot()


@pytest.fixture
async def target(robot_host: str, robot: StaticRobot) -> AsyncIterator[Target]:
    async with emulator(robot_host, robot) as target:
        yield target


hmi = hmi_fixture()


# --------------------------------------------------------------------------- reading


async def test_read_endpoints(hmi: Running) -> None:
    async with hmi.client() as client:
        layout = (await client.get("/api/v1/layout")).json()
        assert layout["layout_version"] == 1 or "version" in json.dumps(layout)
        frame = (await client.get("/api/v1/frame")).json()
        assert frame["stale"] is False
        assert frame["frame"]["robot_state_name"] == "STANDALONE_STANDBY"
        assert 0 <= frame["age_s"] < 5
        status = (await client.get("/api/v1/status")).json()
        connection = status["connection"]
        assert connection["state"] == "connected"
        assert connection["mode"] == "exclusive_owner"
        assert connection["rpi_ms"] == 10.0
        assert connection["packets_in"] > 0
        assert status["control"] == {"holder": None}
        command = (await client.get("/api/v1/command")).json()
        assert command["run"] is False
        assert len(command["image"]["controlbox_do"]) == 16
        assert (await client.get("/healthz")).json() == {"ok": True, "problems": []}
        assert (await client.get("/readyz")).json() == {
            "ready": True,
            "reason": None,
            "robot": None,
        }
        metrics = (await client.get("/metrics")).text
        assert 'cobot_hmi_connection_state{robot="robot",state="connected"} 1.0' in metrics
        assert 'interval_seconds_bucket{le="0.01000",robot="robot"}' in metrics
        assert 'cobot_hmi_writes_total{outcome="confirmed",robot="robot"}' in metrics
        assert (await client.get("/docs")).status_code == 200
        openapi = (await client.get("/openapi.json")).json()
        assert "/api/v1/command" in openapi["paths"]


async def test_view_requires_login_setting(
    target: Target, robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    settings = service_settings(
        robot_host, target.tcp_port, plc_host, tmp_path, view_requires_login=True
    )
    async with running_service(settings) as hmi:
        async with hmi.client() as anonymous:
            answer = await anonymous.get("/api/v1/frame")
            assert answer.status_code == 401
            assert "login required" in answer.json()["detail"]["reason"]
            assert (await anonymous.get("/healthz")).status_code == 200
        async with hmi.client(await hmi.login(VIEWER)) as viewer:
            assert (await viewer.get("/api/v1/frame")).status_code == 200


# --------------------------------------------------------------------------- login


async def test_login_cookie_bearer_logout(hmi: Running) -> None:
    async with hmi.client() as client:
        answer = await client.post(
            "/api/v1/auth/login", json={"username": OPERATOR[0], "password": OPERATOR[1]}
        )
        assert answer.status_code == 200
        body = answer.json()
        assert body["user"] == {"name": OPERATOR[0], "role": "operator"}
        cookie = answer.headers["set-cookie"]
        assert "cobot_session=" in cookie
        assert "HttpOnly" in cookie
        assert "samesite=strict" in cookie.lower()
        # The cookie alone identifies the session (the client keeps it).
        assert (await client.get("/api/v1/auth/me")).json()["user"]["name"] == OPERATOR[0]
        # A browser says where a cookie request comes from (security.py refuses it otherwise).
        own_page = {"origin": hmi.base_url}
        assert (await client.post("/api/v1/auth/logout", headers=own_page)).status_code == 200
        assert (await client.get("/api/v1/auth/me")).json() == {"user": None}
    async with hmi.client(body["token"]) as bearer:  # logged out: the token is dead too
        assert (await bearer.get("/api/v1/auth/me")).json() == {"user": None}
    token = await hmi.login(VIEWER)
    async with hmi.client(token) as bearer:
        assert (await bearer.get("/api/v1/auth/me")).json()["user"]["role"] == "viewer"


async def test_failed_logins_are_slowed_down(hmi: Running) -> None:
    async with hmi.client() as client:
        wrong = {"username": OPERATOR_2[0], "password": "not-the-password"}
        statuses = [
            (await client.post("/api/v1/auth/login", json=wrong)).status_code for _ in range(3)
        ]
        assert statuses == [401, 401, 401]
        throttled = await client.post(
            "/api/v1/auth/login", json={"username": OPERATOR_2[0], "password": OPERATOR_2[1]}
        )
        assert throttled.status_code == 429  # even the right password must wait now
        assert int(throttled.headers["retry-after"]) >= 1
        assert "too many failed logins" in throttled.json()["detail"]["reason"]
        unknown = await client.post("/api/v1/auth/login", json={"username": "", "password": "x"})
        assert unknown.status_code == 422
        assert unknown.json()["detail"]["field"] == "username"
    metrics = await hmi.metrics()
    assert 'cobot_hmi_logins_total{outcome="throttled"} 1.0' in metrics


async def test_roles_gate_audit_and_writes(hmi: Running) -> None:
    async with hmi.client() as anonymous:
        answer = await anonymous.get("/api/v1/audit")
        assert answer.status_code == 401
        assert answer.json()["detail"]["reason"].startswith("login required")
        assert (await anonymous.post("/api/v1/control/take")).status_code == 401
        write = await anonymous.patch("/api/v1/command", json={"tool_do": {"0": True}})
        assert write.status_code == 401
    async with hmi.client(await hmi.login(VIEWER)) as viewer:
        # The event log is read by anyone who may view; the audit trail (users and addresses)
        # needs an operator.
        assert (await viewer.get("/api/v1/events")).status_code == 200
        answer = await viewer.get("/api/v1/audit")
        assert answer.status_code == 403
        assert "operator role" in answer.json()["detail"]["reason"]
        assert (await viewer.post("/api/v1/control/take")).status_code == 403
        write = await viewer.patch("/api/v1/command", json={"tool_do": {"0": True}})
        assert write.status_code == 403
        assert "operator" in write.json()["detail"]["reason"]
    async with hmi.client(await hmi.login(OPERATOR)) as operator:
        audit = (await operator.get("/api/v1/audit")).json()
        # Newest first: the viewer's write and take (through the write pipeline's authorization,
        # audited); anonymous attempts are refused before any database work (no row).
        rows = [(item["action"], item["outcome"], item["user"]) for item in audit["items"]]
        assert rows == [
            ("write", "forbidden", VIEWER[0]),
            ("control.take", "forbidden", VIEWER[0]),
        ]


# --------------------------------------------------------------------------- control


async def test_control_take_is_bumpless_and_exclusive(
    hmi: Running, target: Target, robot: StaticRobot
) -> None:
    robot.consume_command(robot.command_image()._replace(tool_do=(True,) * 6), 0.0)
    await eventually(
        lambda: (
            hmi.service.default_robot.frames.latest
            and hmi.service.default_robot.frames.latest[2].tool_do[0]
        )
    )
    olivia, oscar = await hmi.login(OPERATOR), await hmi.login(OPERATOR_2)
    async with hmi.client(olivia) as first, hmi.client(oscar) as second:
        taken = await first.post("/api/v1/control/take")
        assert taken.status_code == 200, taken.text
        assert taken.json()["holder"]["user"] == OPERATOR[0]
        command = (await first.get("/api/v1/command")).json()
        assert command["run"] is True
        # Bumpless: the image is what the robot already did.
        assert command["image"]["tool_do"] == [True] * 6
        await asyncio.sleep(0.1)
        assert robot.command_image().tool_do == (True,) * 6
        refused = await second.post("/api/v1/control/take")
        assert refused.status_code == 409
        assert OPERATOR[0] in refused.json()["detail"]["reason"]
        assert (await second.post("/api/v1/control/release")).status_code == 409
        status = (await second.get("/api/v1/status")).json()
        assert status["control"]["holder"]["user"] == OPERATOR[0]
        assert (await first.post("/api/v1/control/take")).status_code == 200  # idempotent
        released = await first.post("/api/v1/control/release")
        assert released.json() == {"holder": None}
        assert (await first.get("/api/v1/command")).json()["run"] is False
        assert (await second.post("/api/v1/control/take")).status_code == 200
    async with hmi.client(await hmi.login(ADMIN)) as admin:
        assert (await admin.post("/api/v1/control/release")).json() == {"holder": None}
        audit = (await admin.get("/api/v1/audit?limit=20")).json()["items"]
        reasons = [(i["action"], i["outcome"], i["reason"]) for i in audit]
        assert ("control.release", "released", "released by an admin") in reasons
        assert ("control.take", "refused", "held") in reasons


async def test_control_released_on_logout_and_expiry(
    target: Target, robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    settings = service_settings(robot_host, target.tcp_port, plc_host, tmp_path, session_ttl_s=1.0)
    async with running_service(settings) as hmi:
        async with hmi.client(await hmi.login(OPERATOR)) as client:
            assert (await client.post("/api/v1/control/take")).status_code == 200
            await client.post("/api/v1/auth/logout")
        await eventually(lambda: hmi.service.control.holder is None)
        assert hmi.service.link.run is False
        async with hmi.client(await hmi.login(OPERATOR)) as client:
            assert (await client.post("/api/v1/control/take")).status_code == 200
        # Nobody uses the session: it expires within a second and control goes with it.
        await eventually(lambda: hmi.service.control.holder is None)
        assert hmi.service.link.run is False

        # Announced once the release is audited (after the holder is gone): wait for the log.
        async def control_events() -> list[object]:
            await hmi.service.store.flush_events()
            page = await hmi.service.store.events_page("control", 10, 0)
            return [item["reason"] for item in page.items]

        async def all_four() -> bool:
            return len(await control_events()) >= 4

        await eventually_async(all_four)
        reasons = await control_events()
        assert reasons[:4] == ["session expired", "taken", "logged out", "taken"]


# --------------------------------------------------------------------------- writes


async def test_writes_are_confirmed_by_the_robot(hmi: Running, robot: StaticRobot) -> None:
    async with hmi.client(await hmi.login(OPERATOR)) as client:
        assert (await client.post("/api/v1/control/take")).status_code == 200
        body = {
            "controlbox_do": {"3": True},
            "tool_do": {"1": True},
            "analog_output": {"0": 12.5},
            "analog_output_type": {"0": 0},
        }
        answer = await client.patch("/api/v1/command", json=body)
        assert answer.status_code == 200, answer.text
        result = answer.json()
        assert result["outcome"] == "confirmed"
        assert result["image"]["controlbox_do"][3] is True
        assert result["latency_ms"] > 0
        # It names that frame as the stream numbers frames: shown by now, at or after it.
        assert 0 < result["seq"] <= hmi.service.default_robot.frames.seq
        # Confirmed means the robot's own frame already shows it.
        frame = (await client.get("/api/v1/frame")).json()["frame"]
        assert frame["controlbox_do"][3] is True
        assert frame["tool_do"][1] is True
        assert frame["analog_output"][0] == 12.5
        assert robot.command_image().analog_output[0] == 12.5
        # Voltage with its range, in one request.
        volts = {"analog_output_type": {"1": 1}, "analog_output": {"1": 7.5}}
        assert (await client.patch("/api/v1/command", json=volts)).status_code == 200
        # Bit input registers: confirmed once the O→T packet carrying them went out.
        registers = await client.patch(
            "/api/v1/command", json={"bit_input_registers": {"40": True, "63": True}}
        )
        assert registers.status_code == 200
        assert registers.json()["image"]["bit_input_registers"][40] is True
        assert registers.json()["seq"] is None  # no frame confirms a register: its packet does
        await eventually(lambda: robot.command_image().bit_input_registers[63])
        # Full arrays work as well as index maps.
        full = await client.patch("/api/v1/command", json={"tool_do": [False] * 6})
        assert full.status_code == 200
        audit = (await client.get("/api/v1/audit?limit=1")).json()["items"][0]
        assert audit["fields"] == [f"tool_do.{i}" for i in range(6)]
        assert audit["before"]["tool_do.1"] is True
        assert audit["requested"]["tool_do.1"] is False
        assert audit["outcome"] == "confirmed"


async def test_write_refusals(hmi: Running, robot: StaticRobot) -> None:
    olivia, oscar = await hmi.login(OPERATOR), await hmi.login(OPERATOR_2)
    async with hmi.client(olivia) as client, hmi.client(oscar) as other:
        not_holding = await client.patch("/api/v1/command", json={"tool_do": {"0": True}})
        assert not_holding.status_code == 409
        assert "take control first" in not_holding.json()["detail"]["reason"]
        assert (await client.post("/api/v1/control/take")).status_code == 200
        held = await other.patch("/api/v1/command", json={"tool_do": {"0": True}})
        assert held.status_code == 409
        assert OPERATOR[0] in held.json()["detail"]["reason"]
        before = (await client.get("/api/v1/command")).json()["image"]
        invalid = [
            ({"controlbox_do": {"3": True}, "analog_output": {"0": 30.0}}, "analog_output.0"),
            ({"controlbox_do": {"3": True}, "tool_do": {"6": True}}, "tool_do.6"),
            ({"analog_output_type": {"0": 1}, "analog_output": {"0": 10.5}}, "analog_output.0"),
            ({"analog_output_type": {"1": 3}}, "analog_output_type.1"),
            ({"controlbox_do": {"3": "yes"}}, "controlbox_do.3"),
            ({"robot_state": 3}, "robot_state"),
        ]
        for body, field in invalid:
            answer = await client.patch("/api/v1/command", json=body)
            assert answer.status_code == 422, body
            assert answer.json()["detail"]["field"] == field
            assert answer.json()["detail"]["reason"]
        garbage = await client.patch(
            "/api/v1/command", content=b"{not json", headers={"Content-Type": "application/json"}
        )
        assert garbage.status_code == 422
        assert "not JSON" in garbage.json()["detail"]["reason"]
        # Nothing of any invalid request was applied.
        assert (await client.get("/api/v1/command")).json()["image"] == before
        assert robot.command_image().controlbox_do[3] is False
        audit = (await client.get("/api/v1/audit?limit=50")).json()["items"]
        outcomes = [item["outcome"] for item in audit if item["action"] == "write"]
        assert outcomes.count("invalid") == 7
        assert outcomes.count("refused") == 2
    metrics = await hmi.metrics()
    assert 'cobot_hmi_writes_total{outcome="invalid",robot="robot"} 7.0' in metrics


async def test_write_timeout_reports_what_the_robot_shows(
    target: Target, robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    # A long connection timeout (RPI × 256): the silent robot stays connected while the write
    # waits for a frame that never comes.
    settings = service_settings(
        robot_host,
        target.tcp_port,
        plc_host,
        tmp_path,
        write_timeout_ms=300.0,
        timeout_multiplier=6,
    )
    async with running_service(settings) as hmi, hmi.client(await hmi.login(OPERATOR)) as client:
        assert (await client.post("/api/v1/control/take")).status_code == 200
        target.faults.t2o_silent = True
        answer = await client.patch(
            "/api/v1/command", json={"controlbox_do": {"5": True}, "analog_output": {"1": 9.0}}
        )
        target.faults.t2o_silent = False
        assert answer.status_code == 504
        detail = answer.json()["detail"]
        assert "did not show the new outputs within 300 ms" in detail["reason"]
        assert detail["robot_reports"] == {"controlbox_do.5": False, "analog_output.1": 0.0}
        audit = (await client.get("/api/v1/audit?limit=1")).json()["items"][0]
        assert audit["outcome"] == "timeout"
        assert audit["reason"] == detail["reason"]


async def test_input_only_mode_is_read_only(
    target: Target, robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    settings = service_settings(robot_host, target.tcp_port, plc_host, tmp_path, input_only=True)
    async with running_service(settings) as hmi, hmi.client(await hmi.login(OPERATOR)) as client:
        status = (await client.get("/api/v1/status")).json()["connection"]
        assert status["mode"] == "input_only"
        assert status["state"] == "connected"
        take = await client.post("/api/v1/control/take")
        assert take.status_code == 409
        assert "read-only" in take.json()["detail"]["reason"]
        write = await client.patch("/api/v1/command", json={"tool_do": {"0": True}})
        assert write.status_code == 409
        assert "read-only" in write.json()["detail"]["reason"]


async def test_not_connected_refuses_writes(plc_host: str, robot_host: str, tmp_path: Path) -> None:
    settings = service_settings(robot_host, 1, plc_host, tmp_path)  # nobody listens there
    async with (
        running_service(settings, wait_connected=False) as hmi,
        hmi.client(await hmi.login(OPERATOR)) as client,
    ):
        ready = await client.get("/readyz")
        assert ready.status_code == 503
        assert ready.json()["ready"] is False
        assert ready.json()["reason"]
        take = await client.post("/api/v1/control/take")
        assert take.status_code == 409
        assert "not connected" in take.json()["detail"]["reason"]
        write = await client.patch("/api/v1/command", json={"tool_do": {"0": True}})
        assert write.status_code == 409
        assert "not connected" in write.json()["detail"]["reason"]
        frame = (await client.get("/api/v1/frame")).json()
        assert frame == {
            "robot": "robot",
            "frame": None,
            "received_at": None,
            "age_s": None,
            "stale": True,
        }


# --------------------------------------------------------------------------- audit, events


async def test_audit_and_events_pages_and_csv(hmi: Running) -> None:
    async with hmi.client(await hmi.login(OPERATOR)) as client:
        await client.post("/api/v1/control/take")
        for i in range(5):
            answer = await client.patch("/api/v1/command", json={"controlbox_do": {str(i): True}})
            assert answer.status_code == 200
        page = (await client.get("/api/v1/audit?limit=2&offset=1")).json()
        assert page["total"] == 6
        assert [item["fields"] for item in page["items"]] == [
            ["controlbox_do.3"],
            ["controlbox_do.2"],
        ]
        item = page["items"][0]
        assert item["user"] == OPERATOR[0]
        assert item["client"].startswith("127.")  # the caller's address
        assert item["before"] == {"controlbox_do.3": False}
        answer = await client.get("/api/v1/audit?format=csv&limit=100000")  # the UI export
        assert answer.headers["content-type"].startswith("text/csv")
        rows = list(csv.DictReader(io.StringIO(answer.text)))
        assert len(rows) == 6
        assert rows[-1]["action"] == "control.take"
        for query, field in (
            ("/api/v1/audit?limit=0", "limit"),
            ("/api/v1/audit?limit=100001", "limit"),
            ("/api/v1/audit?offset=-1", "offset"),
            ("/api/v1/audit?format=xml", "format"),
            ("/api/v1/events?kind=bogus", "kind"),
        ):
            answer = await client.get(query)
            assert answer.status_code == 422, query
            assert answer.json()["detail"]["field"] == field, query
        await hmi.service.store.flush_events()
        events = (await client.get("/api/v1/events?limit=100")).json()
        kinds = {item["kind"] for item in events["items"]}
        assert {"connection", "robot_state", "control", "write"} <= kinds
        states = (await client.get("/api/v1/events?kind=robot_state")).json()["items"]
        assert states[-1]["to_name"] == "STANDALONE_STANDBY"
        assert states[-1]["robot"] == "robot"
        connection = (await client.get("/api/v1/events?kind=connection&format=csv")).text
        assert "connected" in connection


# --------------------------------------------------------------------------- frontend


async def test_frontend_served_with_spa_fallback(
    target: Target, robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    dist = tmp_path / "dist"
    (dist / "assets").mkdir(parents=True)
    (dist / "index.html").write_text("<!doctype html><title>HMI</title>")
    (dist / "assets" / "app.js").write_text("console.log('hmi')")
    settings = service_settings(
        robot_host, target.tcp_port, plc_host, tmp_path / "state", frontend_dir=dist
    )
    async with running_service(settings) as hmi, hmi.client() as client:
        for path in ("/", "/kiosk", "/kiosk/"):
            answer = await client.get(path)
            assert answer.status_code == 200
            assert "<title>HMI</title>" in answer.text
        assert (await client.get("/assets/app.js")).text == "console.log('hmi')"
        assert (await client.get("/assets/missing.js")).status_code == 404
        assert (await client.get("/api/v1/nothing")).status_code == 404
        assert (await client.get("/../../etc/passwd")).status_code in (200, 404)
        assert "root:" not in (await client.get("/%2e%2e/%2e%2e/etc/passwd")).text

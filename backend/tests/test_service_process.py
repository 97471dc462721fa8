"""The service as processes do it: audit rows surviving ``kill -9`` right after a confirmed
write, reconnection after the emulator restarts, and ``cobot-hmi demo`` end to end (emulator
process, service, credentials printed once, Ctrl-C stopping both with a Forward Close)."""

from __future__ import annotations

import asyncio
import contextlib
import signal
import sqlite3
from pathlib import Path

import httpx
import orjson
import pytest
from websockets.asyncio.client import connect

from cobot_hmi.service.access.users import Role, UsersFile
from conftest import free_tcp_port
from process_support import PROCESS_DEADLINE_S, cli_process, read_until, wait_ready
from service_support import (
    DEADLINE_S,
    OPERATOR,
    emulator,
    eventually,
    running_service,
    service_settings,
)

pytestmark = pytest.mark.timeout(180)


async def test_audit_survives_kill_9(robot_host: str, plc_host: str, tmp_path: Path) -> None:
    UsersFile(tmp_path / "users.json").add(OPERATOR[0], Role.OPERATOR, OPERATOR[1])
    port = free_tcp_port(plc_host)
    base_url = f"http://{plc_host}:{port}"
    async with (
        emulator(robot_host) as target,
        cli_process(
            "serve",
            "--robot",
            robot_host,
            "--robot-tcp-port",
            str(target.tcp_port),
            "--local-host",
            plc_host,
            "--host",
            plc_host,
            "--port",
            str(port),
            "--state-dir",
            str(tmp_path),
            "--timeout-multiplier",
            "5",
            # A write confirmed by the robot's frame: a loaded machine takes longer than the
            # default second (a run at load 20 refused it), and this test is about the audit.
            "--write-timeout-ms",
            "20000",
        ) as service,
    ):
        await wait_ready(base_url, service)
        async with httpx.AsyncClient(base_url=base_url, timeout=DEADLINE_S) as client:
            login = await client.post(
                "/api/v1/auth/login", json={"username": OPERATOR[0], "password": OPERATOR[1]}
            )
            assert login.status_code == 200, login.text
            # As a script: the bearer token (the cookie alone is for the browser's own pages).
            client.headers["authorization"] = f"Bearer {login.json()['token']}"
            take = await client.post("/api/v1/control/take")
            assert take.status_code == 200, take.text
            write = await client.patch("/api/v1/command", json={"controlbox_do": {"7": True}})
            assert write.status_code == 200, write.text
            service.send_signal(signal.SIGKILL)  # right after the answer: no clean shutdown
        await service.wait()
        assert service.returncode == -signal.SIGKILL
    with contextlib.closing(sqlite3.connect(tmp_path / "hmi.db")) as db:
        rows = db.execute("SELECT action, fields, outcome, user FROM audit ORDER BY id").fetchall()
    assert rows == [
        ("control.take", "[]", "granted", OPERATOR[0]),
        ("write", '["controlbox_do.7"]', "confirmed", OPERATOR[0]),
    ]


async def test_reconnects_after_the_emulator_restarts(
    robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    tcp_port = free_tcp_port(robot_host)
    settings = service_settings(robot_host, tcp_port, plc_host, tmp_path)
    async with running_service(settings, wait_connected=False) as hmi:
        async with emulator(robot_host, tcp_port=tcp_port):
            assert await hmi.service.link.wait_connected(DEADLINE_S)
        # The emulator is gone: the service notices and keeps trying.
        await eventually(lambda: hmi.service.link.state.value in ("lost", "connecting"))
        async with connect(hmi.ws_url) as stream:
            hello = orjson.loads(await stream.recv())
            assert hello["connection"]["state"] != "connected"
            async with emulator(robot_host, tcp_port=tcp_port):
                states: list[str] = []
                frames = 0
                while "connected" not in states or frames < 20:
                    message = orjson.loads(await asyncio.wait_for(stream.recv(), DEADLINE_S))
                    if message["type"] == "event" and message["event"]["kind"] == "connection":
                        states.append(message["event"]["state"])
                    if message["type"] == "frames":
                        frames += len(message["frames"])
                async with hmi.client() as client:
                    assert (await client.get("/readyz")).status_code == 200
        await hmi.service.store.flush_events()
        page = await hmi.service.store.events_page("connection", 100, 0)
        seen = [item["state"] for item in reversed(page.items)]
        first_up = seen.index("connected")
        down = seen.index("lost", first_up)
        assert "connected" in seen[down:]


async def test_demo_runs_and_stops_cleanly(robot_host: str, plc_host: str, tmp_path: Path) -> None:
    dist = tmp_path / "dist"
    dist.mkdir()
    (dist / "index.html").write_text("<!doctype html><title>demo HMI</title>")
    robot_tcp_port, http_port = free_tcp_port(robot_host), free_tcp_port(plc_host)
    base_url = f"http://{plc_host}:{http_port}"
    async with cli_process(
        "demo",
        "--robot-host",
        robot_host,
        "--robot-tcp-port",
        str(robot_tcp_port),
        "--control-port",
        "0",
        "--local-host",
        plc_host,
        "--host",
        plc_host,
        "--port",
        str(http_port),
        "--state-dir",
        str(tmp_path / "state"),
        "--frontend-dir",
        str(dist),
    ) as demo:
        output = await read_until(demo, "with password")
        password = output[-1].split("with password ")[1].split("'")[1]
        await wait_ready(base_url, demo)
        async with httpx.AsyncClient(base_url=base_url, timeout=DEADLINE_S) as client:
            assert "demo HMI" in (await client.get("/")).text
            login = await client.post(
                "/api/v1/auth/login", json={"username": "operator", "password": password}
            )
            assert login.status_code == 200
            assert login.json()["user"]["role"] == "operator"
        demo.send_signal(signal.SIGINT)
        rest, _ = await asyncio.wait_for(demo.communicate(), PROCESS_DEADLINE_S)
    text = "".join(output) + rest.decode()
    assert demo.returncode == 0, text
    assert text.count(password) == 1  # shown once
    assert "closed: Forward Close" in text
    assert "cobot-hmi demo: stopped." in text

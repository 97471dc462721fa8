"""A login session idles out on its person's actions, not on its page's requests (issue 38):
against the real service over real sockets, with plain HTTP and WebSocket clients that do
nothing the page does not (no header of ours, no cooperation): reads (the page's polling, a
stream's reconnection) never renew a session, a person's actions do (a write, taking control,
``POST /api/v1/auth/activity`` which the page sends on clicks and keys), and an expired
session's control is released, its streams closed with the reason."""

from __future__ import annotations

import asyncio
import time
from pathlib import Path

import pytest
from websockets.asyncio.client import ClientConnection, connect
from websockets.exceptions import ConnectionClosed

from cobot_hmi.emulator.target import Target
from service_support import (
    OPERATOR,
    eventually,
    eventually_async,
    running_service,
    service_settings,
)

pytestmark = pytest.mark.timeout(180)

TTL_S = 10.0
"""The sessions' idle lifetime here: short, but long enough that a busy machine's slow request
(several seconds at load 12, beside a fresh clone's suite) never ends a session the test keeps
alive, nor keeps one the test lets idle out."""
READS = ("/api/v1/status", "/api/v1/auth/me", "/api/v1/alarms", "/api/v1/robots")
"""What a panel polls (about 48 of these per 30 s renewed a session before)."""


async def _read_until_closed(stream: ClientConnection) -> tuple[int, str]:
    """Read (a stream not read is closed as stalled) until the service closes it: its code
    and reason."""
    try:
        while True:
            await stream.recv()
    except ConnectionClosed as closed:
        frame = closed.rcvd
    return (frame.code, frame.reason) if frame is not None else (0, "no close frame")


async def test_reads_never_renew_a_session_and_expiry_releases_control(
    target: Target, robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    settings = service_settings(
        robot_host, target.tcp_port, plc_host, tmp_path, session_ttl_s=TTL_S
    )
    async with running_service(settings) as hmi:
        token = await hmi.login(OPERATOR)
        headers = {"Authorization": f"Bearer {token}"}
        async with (
            hmi.client(token) as client,
            connect(
                hmi.robot_ws_url("robot"), additional_headers=headers, open_timeout=60
            ) as stream,
        ):
            reading = asyncio.create_task(_read_until_closed(stream))
            took = await client.post("/api/v1/control/take")
            assert took.status_code == 200, took.text
            acted_at = time.monotonic()  # the person's last action
            first = (await client.get("/api/v1/auth/me")).json()
            assert first["user"]["name"] == OPERATOR[0]
            assert first["idle_timeout_s"] == TTL_S
            # The page polls, many times a second, for well past the lifetime.
            polls = 0
            while time.monotonic() - acted_at < 2.5 * TTL_S:
                for path in READS:
                    await client.get(path)
                    polls += 1
                await asyncio.sleep(0.05)
            assert polls > 40
            # The person comes back: the session has idled out, the write is refused.
            late = await client.patch("/api/v1/command", json={"tool_do": {"0": True}})
            assert late.status_code == 401, late.text
            assert (await client.get("/api/v1/auth/me")).json()["user"] is None
            # Its stream was closed with the reason, its control released.
            code, reason = await asyncio.wait_for(reading, 30)
            assert (code, reason) == (1008, "session ended: session expired")
        await eventually(lambda: hmi.service.default_robot.control.holder is None)

        async def released() -> bool:
            await hmi.service.store.flush_events()
            page = await hmi.service.store.events_page("control", 10, 0)
            return any(item["reason"] == "session expired" for item in page.items)

        await eventually_async(released)


async def test_a_persons_actions_keep_a_session_and_reads_do_not(
    target: Target, robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    settings = service_settings(
        robot_host, target.tcp_port, plc_host, tmp_path, session_ttl_s=TTL_S
    )
    async with running_service(settings) as hmi:
        token = await hmi.login(OPERATOR)
        async with hmi.client(token) as client:
            # A read leaves the deadline where it was: the time left only shrinks.
            before = (await client.get("/api/v1/auth/me")).json()["idle_expires_in_s"]
            await asyncio.sleep(0.3)
            for path in READS:
                assert (await client.get(path)).status_code == 200
            after = (await client.get("/api/v1/auth/me")).json()["idle_expires_in_s"]
            assert after <= before - 0.25
            # A person's clicks (the page reports them) keep it alive past several lifetimes.
            started = time.monotonic()
            while time.monotonic() - started < 2.5 * TTL_S:
                acted = await client.post("/api/v1/auth/activity")
                assert acted.status_code == 200, acted.text
                me = acted.json()
                assert me["user"]["name"] == OPERATOR[0]
                assert me["idle_timeout_s"] == TTL_S
                # Renewed by this report: a whole lifetime left, less the answer's own time.
                assert TTL_S - 3.0 <= me["idle_expires_in_s"] <= TTL_S
                await client.get("/api/v1/status")
                await asyncio.sleep(0.25)
            # So does a write.
            assert (await client.post("/api/v1/control/take")).status_code == 200
            assert (await client.post("/api/v1/control/release")).status_code == 200
            me = (await client.get("/api/v1/auth/me")).json()
            assert me["user"]["name"] == OPERATOR[0]
            # Logged out, the activity report is refused with the reason.
            assert (await client.post("/api/v1/auth/logout")).status_code == 200
            gone = await client.post("/api/v1/auth/activity")
            assert gone.status_code == 401
            assert "log in again" in gone.json()["detail"]["reason"]

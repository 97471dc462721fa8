"""A session that ends closes its open WebSockets: logout, its user removed or given another
role, its API token revoked. Each of the session's streams is closed with 1008 (policy
violation) and the reason; other streams stay open and carry a ``session`` event, which the
event log keeps. The service on loopback against the emulator, real WebSocket clients; the
``Sessions`` watchers on their own too."""

from __future__ import annotations

import asyncio
import contextlib
import json
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import pytest

from cobot_hmi.service.access.auth import Session, Sessions
from cobot_hmi.service.access.users import Role, User, UsersFile
from cobot_hmi.service.api.models import EVENT
from cobot_hmi.service.api.routes.stream import CLOSE_SESSION_ENDED, close_reason
from service_support import (
    ADMIN,
    OPERATOR,
    VIEWER,
    Running,
    emulator,
    eventually,
    running_service,
    service_settings,
)
from test_service_stream import Recorder, recorder

pytestmark = pytest.mark.timeout(120)


@pytest.fixture
async def hmi(robot_host: str, plc_host: str, tmp_path: Path) -> AsyncIterator[Running]:
    async with emulator(robot_host) as target:
        settings = service_settings(robot_host, target.tcp_port, plc_host, tmp_path)
        async with running_service(settings) as running:
            yield running


def stream(url: str, token: str | None = None) -> contextlib.AbstractAsyncContextManager[Recorder]:
    """A stream (``test_service_stream.recorder``: every message kept and validated), opened
    with ``token``'s session."""
    return recorder(url, additional_headers={"Authorization": f"Bearer {token}"} if token else None)


async def opened(*streams: Recorder) -> None:
    await eventually(lambda: all(s.messages for s in streams))


async def closed(reading: Recorder) -> tuple[int, str]:
    """The code and reason of the close frame the server sent, once it came."""
    await eventually(lambda: reading.closed is not None)
    assert reading.closed is not None and reading.closed.rcvd is not None
    return reading.closed.rcvd.code, reading.closed.rcvd.reason


def session_events(reading: Recorder) -> list[Any]:
    return [m["event"] for m in reading.of("event") if m["event"]["kind"] == "session"]


async def test_logout_closes_the_sessions_streams_and_says_so(hmi: Running) -> None:
    token = await hmi.login(OPERATOR)
    other = await hmi.login(OPERATOR)  # the same user's second session stays
    url = hmi.robot_ws_url("robot")
    async with (
        stream(url) as anonymous,
        stream(url, other) as second_session,
        stream(url, token) as first,
        stream(hmi.ws_url, token) as deprecated_path,
    ):
        await opened(anonymous, second_session, first, deprecated_path)
        async with hmi.client(token) as client:
            assert (await client.post("/api/v1/auth/logout")).status_code == 200
        for ended in (first, deprecated_path):
            assert await closed(ended) == (CLOSE_SESSION_ENDED, "session ended: logged out")
        assert CLOSE_SESSION_ENDED == 1008
        # The others go on: the anonymous stream and the other session's see the event and
        # keep receiving frames.
        await eventually(lambda: bool(session_events(anonymous)))
        frames_then = len(anonymous.frames), len(second_session.frames)
        await eventually(
            lambda: (
                len(anonymous.frames) > frames_then[0]
                and len(second_session.frames) > frames_then[1]
            )
        )
        assert anonymous.closed is None and second_session.closed is None
        [event] = session_events(anonymous)
        assert session_events(second_session) == [event]
    EVENT.validate_python(event)
    assert {k: v for k, v in event.items() if k != "time"} == {
        "kind": "session",
        "robot": "robot",
        "user": OPERATOR[0],
        "session": first.messages[0]["session"],
        "reason": "logged out",
        "streams_closed": 2,
        "text": f"Session of {OPERATOR[0]} ended (logged out): 2 streams closed",
    }
    # The event log keeps it.
    await hmi.service.store.flush_events()
    async with hmi.client(await hmi.login(OPERATOR)) as client:
        page = (await client.get("/api/v1/events?kind=session")).json()
    assert page["total"] == 1
    assert page["items"][0]["reason"] == "logged out"
    assert page["items"][0]["streams_closed"] == 2


def _users(running: Running) -> UsersFile:
    return UsersFile(running.settings.web.users_path)


async def test_a_role_change_or_a_removed_user_closes_the_streams(hmi: Running) -> None:
    url = hmi.robot_ws_url("robot")
    viewer_token = await hmi.login(VIEWER)
    operator_token = await hmi.login(OPERATOR)
    async with stream(url, viewer_token) as viewer, stream(url, operator_token) as operator:
        await opened(viewer, operator)
        # The operator becomes a viewer: the rights the session logged in with are gone.
        await asyncio.to_thread(_users(hmi).add, OPERATOR[0], Role.VIEWER, OPERATOR[1])
        changed = f"session ended: user {OPERATOR[0]}'s role changed to viewer"
        assert await closed(operator) == (1008, changed)
        assert viewer.closed is None
        async with hmi.client(operator_token) as client:
            assert (await client.get("/api/v1/auth/me")).json() == {"user": None}

        # The viewer is removed from the users file (by hand: no verb removes a user).
        path = hmi.settings.web.users_path
        document = json.loads(path.read_text(encoding="utf-8"))
        del document["users"][VIEWER[0]]
        path.write_text(json.dumps(document), encoding="utf-8")
        assert await closed(viewer) == (1008, f"session ended: user {VIEWER[0]} removed")
    await eventually(lambda: not hmi.service.default_robot.hub.clients)
    await hmi.service.store.flush_events()
    async with hmi.client(await hmi.login(ADMIN)) as client:
        page = (await client.get("/api/v1/events?kind=session")).json()
    assert sorted((e["user"], e["reason"], e["streams_closed"]) for e in page["items"]) == [
        (OPERATOR[0], f"user {OPERATOR[0]}'s role changed to viewer", 1),
        (VIEWER[0], f"user {VIEWER[0]} removed", 1),
    ]


async def test_a_revoked_api_token_closes_its_stream(hmi: Running) -> None:
    token = await asyncio.to_thread(_users(hmi).add_token, "kiosk", Role.VIEWER, expires_in_s=None)
    async with stream(hmi.robot_ws_url("robot") + f"?token={token}") as kiosk:
        await opened(kiosk)
        assert kiosk.messages[0]["type"] == "hello"
        assert kiosk.messages[0]["session"] is not None
        await asyncio.to_thread(_users(hmi).revoke_token, "kiosk")
        assert await closed(kiosk) == (1008, "session ended: API token revoked or expired")
    await hmi.service.store.flush_events()
    async with hmi.client(await hmi.login(OPERATOR)) as client:
        page = (await client.get("/api/v1/events?kind=session")).json()
    assert [(e["user"], e["reason"]) for e in page["items"]] == [
        ("token:kiosk", "API token revoked or expired")
    ]


# --------------------------------------------------------------------------- Sessions alone


def _sessions(users: dict[str, User]) -> tuple[Sessions, list[tuple[str, str]]]:
    ended: list[tuple[str, str]] = []
    sessions = Sessions(60.0, lambda s, reason: ended.append((s.id, reason)), None, users.get)
    return sessions, ended


def test_watchers_hear_the_end_once_after_on_end() -> None:
    alice = User("alice", Role.OPERATOR)
    sessions, ended = _sessions({"alice": alice})
    session = sessions.create(alice)
    heard: list[tuple[str, list[tuple[str, str]]]] = []
    sessions.watch(session, lambda reason: heard.append((reason, list(ended))))
    stop = sessions.watch(session, lambda reason: heard.append(("unwatched", [])))
    stop()
    stop()  # idempotent
    sessions.end(session, "logged out")
    sessions.end(session, "logged out")
    # on_end (control released) first, then the watcher; once; the unwatched one never.
    assert heard == [("logged out", [(session.id, "logged out")])]
    # Watching a session that has ended already: told at once.
    late: list[str] = []
    sessions.watch(session, late.append)
    assert late == ["session ended"]


def test_a_failing_watcher_does_not_keep_the_others_open() -> None:
    alice = User("alice", Role.OPERATOR)
    sessions, _ = _sessions({"alice": alice})
    session = sessions.create(alice)
    heard: list[str] = []

    def broken(_: str) -> None:
        raise RuntimeError("a bug")

    sessions.watch(session, broken)
    sessions.watch(session, heard.append)
    sessions.end(session, "logged out")
    assert heard == ["logged out"]


@pytest.mark.parametrize(
    ("now", "reason"),
    [
        ({}, "user alice removed"),
        ({"alice": User("alice", Role.VIEWER)}, "user alice's role changed to viewer"),
    ],
)
def test_a_changed_user_ends_its_sessions_on_use_and_on_sweep(
    now: dict[str, User], reason: str
) -> None:
    alice = User("alice", Role.OPERATOR)
    users = {"alice": alice}
    sessions, ended = _sessions(users)
    on_sweep, on_use = sessions.create(alice), sessions.create(alice)
    heard: list[str] = []
    for session in (on_sweep, on_use):
        sessions.watch(session, heard.append)
    assert sessions.sweep() == 0 and sessions.get(on_use.token) is on_use
    users.clear()
    users.update(now)
    assert sessions.get(on_use.token) is None  # a request with it: anonymous from now on
    assert sessions.sweep() == 1
    assert sorted(ended) == sorted([(on_sweep.id, reason), (on_use.id, reason)])
    assert heard == [reason, reason]
    assert len(sessions) == 0


def test_an_unchanged_user_keeps_its_session() -> None:
    alice = User("alice", Role.OPERATOR)
    sessions, ended = _sessions({"alice": User("alice", Role.OPERATOR)})
    session: Session = sessions.create(alice)
    assert sessions.get(session.token) is session
    assert sessions.sweep() == 0 and ended == []


def test_close_reasons_fit_a_close_frame() -> None:
    long = "session ended: " + "é" * 200
    cut = close_reason(long)
    assert len(cut.encode()) <= 123
    assert long.startswith(cut)
    assert close_reason("session ended: logged out") == "session ended: logged out"

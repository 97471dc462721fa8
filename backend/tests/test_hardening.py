"""The service attacked as a reviewer would, on loopback: every hardening point of
docs/operations.md "Security" against the real service and emulator.

Each test fails without its fix: bodies bounded before they are read (413), Host and
cross-site checks (a page on another port of the same host cannot write or take control,
nor open the stream), the security headers, X-Forwarded-For only from trusted proxies,
anonymous writes refused before any database work and rate-limited, the database's mode,
index keys in canonical ASCII, viewing behind a login with long-lived viewer tokens.
"""

from __future__ import annotations

import asyncio
import json
import os
import stat
import time
from collections.abc import AsyncIterator
from pathlib import Path

import httpx
import pytest
import websockets
from websockets.typing import Origin

from cobot_hmi.emulator.static_robot import StaticRobot
from cobot_hmi.emulator.target import Target
from cobot_hmi.service.access.users import Role, UsersFile
from service_support import (
    DEADLINE_S,
    OPERATOR,
    Running,
    emulator,
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


hmi = hmi_fixture(max_body_bytes=4096, anonymous_write_burst=5, anonymous_writes_per_s=0.01)


def _host(hmi: Running) -> str:
    """The service's HOST:PORT (the Host header a browser sends)."""
    return f"{hmi.settings.web.host}:{hmi.settings.web.port}"


def _origin(hmi: Running, port: int | None = None) -> Origin:
    return Origin(
        f"http://{hmi.settings.web.host}:{hmi.settings.web.port if port is None else port}"
    )


async def _raw_http(hmi: Running, head: bytes, body: bytes = b"") -> tuple[int, bytes]:
    """Send ``head`` (and ``body``) on a fresh TCP connection; the status and the answer."""
    reader, writer = await asyncio.open_connection(hmi.settings.web.host, hmi.settings.web.port)
    try:
        writer.write(head + body)
        await writer.drain()
        async with asyncio.timeout(DEADLINE_S):
            status_line = await reader.readline()
            rest = await reader.read(64 * 1024)
    finally:
        writer.close()
    return int(status_line.split()[1]), status_line + rest


# --------------------------------------------------------------------------- request bodies


async def test_a_body_announced_too_large_is_refused_before_it_is_sent(hmi: Running) -> None:
    # 1 GiB announced, nothing sent: without the bound the route waits to read it all.
    head = (
        f"PATCH /api/v1/command HTTP/1.1\r\nHost: {_host(hmi)}\r\n"
        "Content-Type: application/json\r\nContent-Length: 1073741824\r\n\r\n"
    ).encode()
    status, answer = await _raw_http(hmi, head, b'{"tool_do": ')
    assert status == 413, answer
    assert b"max_body_bytes" in answer
    assert b"connection: close" in answer.lower()


async def test_a_chunked_body_is_cut_off_at_the_limit(hmi: Running) -> None:
    token = await hmi.login(OPERATOR)
    # 8 KiB in 1 KiB chunks and no last chunk: the body never ends. Without the bound the
    # route would wait for the rest; with it, the service answers once the limit is passed.
    head = (
        f"PATCH /api/v1/command HTTP/1.1\r\nHost: {_host(hmi)}\r\n"
        f"Authorization: Bearer {token}\r\nContent-Type: application/json\r\n"
        "Transfer-Encoding: chunked\r\n\r\n"
    ).encode()
    chunk = b"400\r\n" + b"x" * 1024 + b"\r\n"
    status, answer = await _raw_http(hmi, head, chunk * 8)
    assert status == 413, answer
    assert b"max_body_bytes" in answer
    # A chunked body under the limit reaches the route (422: not JSON, rather than 413).
    small = b'4\r\n{"x"\r\n0\r\n\r\n'
    status, answer = await _raw_http(hmi, head, small)
    assert status == 422, answer


async def test_a_body_sent_too_slowly_is_refused(
    target: Target, robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    settings = service_settings(
        robot_host, target.tcp_port, plc_host, tmp_path, http_idle_timeout_s=1.0
    )
    async with running_service(settings) as hmi:
        token = await hmi.login(OPERATOR)
        # 100 bytes announced, 10 sent, then silence: the connection would stay busy for ever.
        head = (
            f"PATCH /api/v1/command HTTP/1.1\r\nHost: {settings.web.host}:{settings.web.port}\r\n"
            f"Authorization: Bearer {token}\r\nContent-Type: application/json\r\n"
            "Content-Length: 100\r\n\r\n"
        ).encode()
        status, answer = await _raw_http(hmi, head, b'{"tool_do"')
        assert status == 408, answer
        assert b"http_idle_timeout_s" in answer
        metrics = await hmi.metrics()
        assert 'cobot_hmi_http_refusals_total{reason="body_too_slow"} 1.0' in metrics


# --------------------------------------------------------------------------- headers, hosts


async def test_answers_carry_the_security_headers(hmi: Running) -> None:
    async with hmi.client() as client:
        for path in ("/api/v1/status", "/", "/kiosk", "/no-such-page"):
            answer = await client.get(path)
            csp = answer.headers["content-security-policy"]
            assert "frame-ancestors 'none'" in csp
            assert "default-src 'self'" in csp
            assert "script-src 'self'" in csp and "unsafe-eval" not in csp
            own = f"{hmi.settings.web.host}:{hmi.settings.web.port}"
            assert f"connect-src 'self' ws://{own} wss://{own};" in csp  # the stream
            assert answer.headers["x-frame-options"] == "DENY"
            assert answer.headers["x-content-type-options"] == "nosniff"
            assert answer.headers["referrer-policy"] == "no-referrer"
        # Refusals by the checks themselves carry them too.
        refused = await client.get("/api/v1/status", headers={"host": "evil.example"})
        assert refused.headers["x-frame-options"] == "DENY"


async def test_other_host_headers_are_refused(hmi: Running) -> None:
    port = hmi.settings.web.port
    async with hmi.client() as client:
        # DNS rebinding: a name the attacker controls, resolved to the HMI's address.
        for host in ("evil.example", f"evil.example:{port}", "127.0.0.1.nip.io"):
            answer = await client.get("/api/v1/status", headers={"host": host})
            assert answer.status_code == 400, host
            assert "allowed_hosts" in answer.json()["detail"]["reason"]
        for host in (f"localhost:{port}", f"{hmi.settings.web.host}:{port}", f"[::1]:{port}"):
            assert (await client.get("/api/v1/status", headers={"host": host})).status_code == 200
    # The stream's handshake too.
    handshake = (
        b"GET /api/v1/stream HTTP/1.1\r\nHost: evil.example\r\nUpgrade: websocket\r\n"
        b"Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
        b"Sec-WebSocket-Version: 13\r\n\r\n"
    )
    status, raw_answer = await _raw_http(hmi, handshake)
    assert status == 403, raw_answer


async def test_allowed_hosts_setting(
    target: Target, robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    settings = service_settings(
        robot_host, target.tcp_port, plc_host, tmp_path, allowed_hosts="hmi.cell.example"
    )
    async with running_service(settings) as hmi, hmi.client() as client:
        good = await client.get("/healthz", headers={"host": "hmi.cell.example"})
        assert good.status_code == 200
        # The IP literal is no longer served once the setting names the hosts.
        assert (await client.get("/healthz")).status_code == 400


# --------------------------------------------------------------------------- cross-site


async def _cookie_login(client: httpx.AsyncClient, user: tuple[str, str]) -> None:
    answer = await client.post(
        "/api/v1/auth/login", json={"username": user[0], "password": user[1]}
    )
    assert answer.status_code == 200, answer.text


async def test_a_page_on_another_port_cannot_take_control(hmi: Running) -> None:
    other = _origin(hmi, hmi.settings.web.port + 1)
    async with hmi.client() as browser:
        await _cookie_login(browser, OPERATOR)
        # The attack: an auto-submitted form on http://same-host:other-port, with the cookie.
        form = await browser.post(
            "/api/v1/control/take",
            content=b"x=1",
            headers={
                "origin": other,
                "content-type": "application/x-www-form-urlencoded",
                "sec-fetch-site": "same-site",
            },
        )
        assert form.status_code == 403, form.text
        assert "cross-origin" in form.json()["detail"]["reason"]
        # Even as JSON (which a form cannot send), another origin is refused.
        json_post = await browser.post("/api/v1/control/take", headers={"origin": other})
        assert json_post.status_code == 403
        write = await browser.patch(
            "/api/v1/command", json={"tool_do": {"0": True}}, headers={"origin": "null"}
        )
        assert write.status_code == 403
        # Without Origin, a browser's Sec-Fetch-Site still tells a foreign page apart.
        fetch = await browser.post("/api/v1/control/take", headers={"sec-fetch-site": "cross-site"})
        assert fetch.status_code == 403
        assert (await browser.get("/api/v1/status")).json()["control"]["holder"] is None
        # A form posted from the HMI's own origin is still not JSON.
        own_form = await browser.post(
            "/api/v1/control/take",
            content=b"x=1",
            headers={"origin": _origin(hmi), "content-type": "application/x-www-form-urlencoded"},
        )
        assert own_form.status_code == 415
        plain = await browser.post(
            "/api/v1/control/take",
            content=b"{}",
            headers={"origin": _origin(hmi), "content-type": "text/plain"},
        )
        assert plain.status_code == 415
        # The cookie without either header: no browser of today sends that; refused too.
        bare = await browser.post("/api/v1/control/take")
        assert bare.status_code == 403
        assert "session cookie" in bare.json()["detail"]["reason"]
        # The HMI's own page (same origin, as the browser says) may.
        own = await browser.post(
            "/api/v1/control/take",
            headers={"origin": _origin(hmi), "sec-fetch-site": "same-origin"},
        )
        assert own.status_code == 200, own.text
        release = await browser.post(
            "/api/v1/control/release", headers={"sec-fetch-site": "same-origin"}
        )
        assert release.status_code == 200
    metrics = await hmi.metrics()
    assert 'cobot_hmi_http_refusals_total{reason="cross_site"} 5.0' in metrics
    assert 'cobot_hmi_http_refusals_total{reason="content_type"} 2.0' in metrics


async def test_allowed_origins_setting(
    target: Target, robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    settings = service_settings(robot_host, target.tcp_port, plc_host, tmp_path)
    extra = f"http://{settings.web.host}:{settings.web.port + 1}"
    settings = settings.replace(allowed_origins=[extra])
    async with running_service(settings) as hmi, hmi.client(await hmi.login(OPERATOR)) as client:
        assert (
            await client.post("/api/v1/control/take", headers={"origin": extra})
        ).status_code == 200
        assert (
            await client.post(
                "/api/v1/control/release", headers={"origin": _origin(hmi, settings.web.port + 2)}
            )
        ).status_code == 403


async def test_the_stream_checks_the_origin(hmi: Running) -> None:
    url = hmi.ws_url
    with pytest.raises(websockets.InvalidStatus) as refused:
        async with websockets.connect(url, origin=_origin(hmi, hmi.settings.web.port + 1)):
            pass
    assert refused.value.response.status_code == 403
    async with websockets.connect(url, origin=_origin(hmi)) as own:
        hello = json.loads(await asyncio.wait_for(own.recv(), DEADLINE_S))
        assert hello["type"] == "hello"
    async with websockets.connect(url) as script:  # no Origin: not a browser
        assert json.loads(await asyncio.wait_for(script.recv(), DEADLINE_S))["type"] == "hello"


# --------------------------------------------------------------------------- forwarded-for


def _from_localhost(hmi: Running, **headers: str) -> httpx.AsyncClient:
    """A client whose connections come from 127.0.0.1 (uvicorn's default trusted proxy)."""
    transport = httpx.AsyncHTTPTransport(local_address="127.0.0.1")
    return httpx.AsyncClient(
        base_url=hmi.base_url, transport=transport, headers=headers, timeout=DEADLINE_S
    )


async def test_forwarded_for_cannot_dodge_the_login_throttle(hmi: Running) -> None:
    async with _from_localhost(hmi) as client:
        statuses = []
        for attempt in range(10):
            # A new user name and a new forged address each time: only the real address is
            # left to count failures against.
            answer = await client.post(
                "/api/v1/auth/login",
                json={"username": f"guess{attempt}", "password": "wrong-password"},
                headers={"x-forwarded-for": f"198.51.100.{attempt}"},
            )
            statuses.append(answer.status_code)
        # Three free failures from the one real address, then it must wait (and each wait
        # doubles, so the attempts catch up with one however slow the machine is).
        assert statuses[:3] == [401, 401, 401]
        assert 429 in statuses[3:]


async def test_forwarded_for_does_not_reach_the_audit_trail(hmi: Running) -> None:
    token = await hmi.login(OPERATOR)
    async with _from_localhost(hmi, authorization=f"Bearer {token}") as client:
        forged = {"x-forwarded-for": "203.0.113.9", "x-forwarded-proto": "https"}
        assert (await client.post("/api/v1/control/take", headers=forged)).status_code == 200
        assert (await client.post("/api/v1/control/release")).status_code == 200
        audit = (await client.get("/api/v1/audit")).json()["items"]
    clients = {item["client"] for item in audit}
    assert clients == {"127.0.0.1"}


async def test_forwarded_for_from_a_trusted_proxy_is_believed(
    target: Target, robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    settings = service_settings(
        robot_host, target.tcp_port, plc_host, tmp_path, trusted_proxies="127.0.0.1"
    )
    async with running_service(settings) as hmi:
        token = await hmi.login(OPERATOR)
        async with _from_localhost(hmi, authorization=f"Bearer {token}") as proxy:
            forwarded = {"x-forwarded-for": "203.0.113.9"}
            assert (await proxy.post("/api/v1/control/take", headers=forwarded)).status_code == 200
            assert (
                await proxy.post("/api/v1/control/release", headers=forwarded)
            ).status_code == 200
            audit = (await proxy.get("/api/v1/audit")).json()["items"]
        assert {item["client"] for item in audit} == {"203.0.113.9"}


# --------------------------------------------------------------------------- anonymous writes


async def test_anonymous_writes_are_refused_before_the_database_and_rate_limited(
    hmi: Running,
) -> None:
    async with hmi.client(await hmi.login(OPERATOR)) as operator:
        rows_before = (await operator.get("/api/v1/audit")).json()["total"]
        async with hmi.client() as anonymous:
            statuses = []
            for attempt in range(12):
                # The deprecated path and the robot's own one share the budget.
                path = "/api/v1/command" if attempt % 2 else "/api/v1/robots/robot/command"
                answer = await anonymous.patch(path, json={"tool_do": {"0": True}})
                statuses.append(answer.status_code)
            take = await anonymous.post("/api/v1/control/take")
        assert statuses[:5] == [401] * 5  # the burst
        assert set(statuses[5:]) == {429}
        assert take.status_code == 429
        assert int(take.headers["retry-after"]) >= 1
        # Not one audit row (no fsync'd commit) for all of them.
        assert (await operator.get("/api/v1/audit")).json()["total"] == rows_before
        # The operator's own writes are not slowed by the anonymous budget.
        assert (await operator.post("/api/v1/control/take")).status_code == 200
        assert (await operator.post("/api/v1/control/release")).status_code == 200
    metrics = await hmi.metrics()
    assert 'cobot_hmi_http_refusals_total{reason="anonymous_write"} 5.0' in metrics
    assert 'cobot_hmi_http_refusals_total{reason="anonymous_throttled"} 8.0' in metrics


async def test_the_database_file_is_private(
    target: Target, robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    settings = service_settings(robot_host, target.tcp_port, plc_host, tmp_path)
    database = settings.web.database_path
    database.parent.mkdir(parents=True, exist_ok=True)
    database.touch(mode=0o644)  # left readable by an older version
    os.chmod(database, 0o644)
    async with running_service(settings) as hmi:
        async with hmi.client(await hmi.login(OPERATOR)) as operator:
            assert (await operator.post("/api/v1/control/take")).status_code == 200
        for path in (database, Path(f"{database}-wal")):
            assert stat.S_IMODE(path.stat().st_mode) == 0o600, path
    fresh = tmp_path / "fresh"
    settings = service_settings(robot_host, target.tcp_port, plc_host, fresh)
    async with running_service(settings):
        assert stat.S_IMODE(settings.web.database_path.stat().st_mode) == 0o600


# --------------------------------------------------------------------------- index keys


@pytest.mark.parametrize("key", ["٣", "１", "²", "03", "+3"])
async def test_index_keys_other_than_ascii_decimal_are_not_applied(hmi: Running, key: str) -> None:
    async with hmi.client(await hmi.login(OPERATOR)) as operator:
        assert (await operator.post("/api/v1/control/take")).status_code == 200
        before = (await operator.get("/api/v1/command")).json()["image"]
        answer = await operator.patch("/api/v1/command", json={"controlbox_do": {key: True}})
        assert answer.status_code == 422, answer.text
        assert (await operator.get("/api/v1/command")).json()["image"] == before


# --------------------------------------------------------------------------- viewing, tokens


async def test_viewer_tokens_for_kiosks_when_viewing_needs_a_login(
    target: Target, robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    settings = service_settings(
        robot_host, target.tcp_port, plc_host, tmp_path, view_requires_login=True
    )
    async with running_service(settings) as hmi:
        users = UsersFile(settings.web.users_path)
        token = users.add_token("kiosk-hall", Role.VIEWER, expires_in_s=30 * 86400.0)
        expired = users.add_token(
            "old-kiosk", Role.VIEWER, expires_in_s=60.0, now=time.time() - 3600.0
        )
        assert json.dumps(json.loads(settings.web.users_path.read_text())).count(token) == 0
        async with hmi.client() as anonymous:
            assert (await anonymous.get("/api/v1/frame")).status_code == 401
        async with hmi.client(token) as kiosk:
            assert (await kiosk.get("/api/v1/frame")).status_code == 200
            me = (await kiosk.get("/api/v1/auth/me")).json()["user"]
            assert me == {"name": "token:kiosk-hall", "role": "viewer"}
            assert (await kiosk.post("/api/v1/control/take")).status_code == 403
        async with websockets.connect(f"{hmi.ws_url}?token={token}") as stream:
            assert json.loads(await asyncio.wait_for(stream.recv(), DEADLINE_S))["type"] == "hello"
        async with websockets.connect(hmi.ws_url) as stream:
            await asyncio.wait_for(stream.wait_closed(), DEADLINE_S)
            assert stream.close_code == 4401
        async with hmi.client(expired) as old:
            assert (await old.get("/api/v1/frame")).status_code == 401
        users.revoke_token("kiosk-hall")
        async with hmi.client(token) as kiosk:
            assert (await kiosk.get("/api/v1/frame")).status_code == 401


async def test_reading_needs_no_login_by_default(hmi: Running) -> None:
    async with hmi.client() as anonymous:
        assert (await anonymous.get("/api/v1/frame")).status_code == 200
    async with websockets.connect(hmi.ws_url) as stream:
        assert json.loads(await asyncio.wait_for(stream.recv(), DEADLINE_S))["type"] == "hello"

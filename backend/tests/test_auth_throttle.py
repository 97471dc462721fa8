"""The login throttle against the real service: a guesser at one address cannot lock a user
out of her own address (per-address and per-user budgets), and API tokens from the command line.

Clients bind their own loopback source addresses (``local_address``), so the service sees two
real, different client addresses.
"""

from __future__ import annotations

import asyncio
import subprocess
import sys
import time
from collections.abc import AsyncIterator

import httpx
import pytest

from cobot_hmi.emulator.target import Target
from conftest import _next_host
from service_support import (
    DEADLINE_S,
    OPERATOR,
    Running,
    emulator,
    hmi_fixture,
)

pytestmark = pytest.mark.timeout(120)

USER_DELAY_MAX_S = 1.0


@pytest.fixture
async def target(robot_host: str) -> AsyncIterator[Target]:
    async with emulator(robot_host) as target:
        yield target


hmi = hmi_fixture(
    login_free_attempts=2,
    login_delay_max_s=600.0,
    login_user_delay_max_s=USER_DELAY_MAX_S,
)


def _client_at(hmi: Running, address: str) -> httpx.AsyncClient:
    transport = httpx.AsyncHTTPTransport(local_address=address)
    return httpx.AsyncClient(base_url=hmi.base_url, transport=transport, timeout=DEADLINE_S)


async def _login(client: httpx.AsyncClient, password: str) -> httpx.Response:
    return await client.post(
        "/api/v1/auth/login", json={"username": OPERATOR[0], "password": password}
    )


async def test_a_guesser_elsewhere_cannot_lock_a_user_out(hmi: Running) -> None:
    guesser_address, user_address = _next_host(), _next_host()
    async with _client_at(hmi, guesser_address) as guesser:
        # Fail until the guesser's own wait is far past the per-user bound (each 429 is
        # waited out: refused attempts do not count).
        failures = 0
        while True:
            asked_at = time.monotonic()
            answer = await _login(guesser, "not-the-password")
            if answer.status_code == 429:
                wait_s = int(answer.headers["retry-after"])
                if failures >= 4:
                    break
                await asyncio.sleep(wait_s)
                continue
            assert answer.status_code == 401, answer.text
            failures += 1
        assert wait_s > 2 * USER_DELAY_MAX_S  # the guesser's address: 4 s and doubling
        async with _client_at(hmi, user_address) as user:
            # The user, from her own address: at most the short per-user wait, then in.
            for _ in range(3):
                answer = await _login(user, OPERATOR[1])
                if answer.status_code != 429:
                    break
                assert int(answer.headers["retry-after"]) <= USER_DELAY_MAX_S
                await asyncio.sleep(USER_DELAY_MAX_S)
            assert answer.status_code == 200, answer.text
        # The guesser is still held back, even with the right password: by its own address's
        # wait, what is left of it (not the user's short one). The throttle runs on real time:
        # what is left is reckoned from the clock (Retry-After is whole seconds, rounded up),
        # so a machine busy for seconds in between only makes it smaller.
        answer = await _login(guesser, OPERATOR[1])
        left_s = wait_s - 1 - (time.monotonic() - asked_at)
        if left_s > 0:
            assert answer.status_code == 429, answer.text
            assert int(answer.headers["retry-after"]) >= left_s
        else:  # (this side stalled for longer than the wait itself)
            assert answer.status_code in (200, 429), answer.text


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "cobot_hmi.cli", *args],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )


async def test_users_token_verb_issues_lists_and_revokes(hmi: Running) -> None:
    state = ["--users-file", str(hmi.settings.web.users_path)]
    issued = await asyncio.to_thread(
        _cli, "users", "token", "kiosk-1", "--expires-days", "30", *state
    )
    assert issued.returncode == 0, issued.stderr
    token = issued.stdout.strip()
    assert token.startswith("chmi_") and len(token) > 40
    assert token not in hmi.settings.web.users_path.read_text()  # only its digest is kept
    listed = await asyncio.to_thread(_cli, "users", "list", *state)
    assert "token:kiosk-1\tviewer\texpires 20" in listed.stdout
    async with hmi.client(token) as kiosk:
        me = (await kiosk.get("/api/v1/auth/me")).json()
        assert me["user"] == {"name": "token:kiosk-1", "role": "viewer"}
    revoked = await asyncio.to_thread(_cli, "users", "revoke", "kiosk-1", *state)
    assert revoked.returncode == 0, revoked.stderr
    async with hmi.client(token) as kiosk:
        assert (await kiosk.get("/api/v1/auth/me")).json() == {"user": None}
    again = await asyncio.to_thread(_cli, "users", "revoke", "kiosk-1", *state)
    assert again.returncode == 2
    assert "no token named 'kiosk-1'" in again.stderr
    bad = await asyncio.to_thread(_cli, "users", "token", "kiosk-2", "--expires-days", "-1", *state)
    assert bad.returncode == 2
    assert "--expires-days" in bad.stderr

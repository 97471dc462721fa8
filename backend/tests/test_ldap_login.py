"""Directory login against a real OpenLDAP ``slapd`` (tests/ldap_support.py) and the real
service on uvicorn: roles from groups (``member`` of ``groupOfNames``, ``uniqueMember`` of
``groupOfUniqueNames``, ``memberOf``), a user in no mapped group refused with a clear
message, a wrong password, a group change between two logins and during a session, injection
attempts refused, the login throttle, slapd stopped mid-run (directory users get "directory
unreachable", the local admin logs in, both audited) and LDAPS with the test's CA.
"""

from __future__ import annotations

import contextlib
from collections.abc import AsyncIterator, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import pytest

from cobot_hmi.emulator.target import Target
from ldap_support import (
    BASE_DN,
    GROUP_ROLES,
    INJECTIONS,
    OPERATORS,
    SERVICE_DN,
    SERVICE_PASSWORD,
    USER_DN_TEMPLATE,
    USERS,
    VIEWERS,
    Slapd,
    needs_slapd,
    running_slapd,
)
from service_support import (
    ADMIN,
    Running,
    emulator,
    eventually_async,
    running_service,
    service_settings,
)

pytestmark = [needs_slapd, pytest.mark.timeout(180)]


@pytest.fixture(scope="session")
def slapd(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Slapd]:
    with running_slapd(tmp_path_factory.mktemp("slapd")) as running:
        yield running


@pytest.fixture
async def target(robot_host: str) -> AsyncIterator[Target]:
    async with emulator(robot_host) as target:
        yield target


def search_then_bind(slapd: Slapd) -> dict[str, Any]:
    return {
        "ldap_url": slapd.url,
        "ldap_search_base": BASE_DN,
        "ldap_bind_dn": SERVICE_DN,
        "ldap_bind_password": SERVICE_PASSWORD,
        "ldap_group_role": GROUP_ROLES,
    }


def dn_template(slapd: Slapd) -> dict[str, Any]:
    return {
        "ldap_url": slapd.url,
        "ldap_user_dn": USER_DN_TEMPLATE,
        "ldap_group_role": GROUP_ROLES,
    }


@dataclass
class Place:
    """Where a test's service runs: its robot, its addresses, its state directory."""

    target: Target
    robot_host: str
    plc_host: str
    state_dir: Path


@pytest.fixture
def place(target: Target, robot_host: str, plc_host: str, tmp_path: Path) -> Place:
    return Place(target, robot_host, plc_host, tmp_path)


@contextlib.asynccontextmanager
async def hmi_with(place: Place, **settings: Any) -> AsyncIterator[Running]:
    config = service_settings(
        place.robot_host, place.target.tcp_port, place.plc_host, place.state_dir, **settings
    )
    async with running_service(config) as running:
        yield running


async def login(client: httpx.AsyncClient, name: str, password: str) -> httpx.Response:
    return await client.post("/api/v1/auth/login", json={"username": name, "password": password})


async def role_of(hmi: Running, name: str) -> str:
    """Log ``name`` in with their directory password; their role as the session has it."""
    async with hmi.client() as client:
        answer = await login(client, name, USERS[name][0])
        assert answer.status_code == 200, answer.text
        me = await client.get("/api/v1/auth/me")  # the session cookie
    role: str = me.json()["user"]["role"]
    assert answer.json()["user"] == {"name": name, "role": role}
    return role


async def login_audit(hmi: Running) -> list[tuple[str, str, str]]:
    """The audit's login rows, oldest first: (user, source, outcome)."""
    async with hmi.client(await hmi.login(ADMIN)) as admin:
        items = (await admin.get("/api/v1/audit?limit=1000")).json()["items"]
    return [
        (row["user"], row["requested"]["source"], row["outcome"])
        for row in reversed(items)
        if row["action"] == "login"
    ]


async def test_directory_users_get_their_groups_roles_and_local_users_stay(
    slapd: Slapd, place: Place
) -> None:
    async with hmi_with(place, **search_then_bind(slapd)) as hmi:
        assert await role_of(hmi, "olga") == "operator"  # member of a groupOfNames
        assert await role_of(hmi, "vera") == "viewer"  # uniqueMember of a groupOfUniqueNames
        assert await role_of(hmi, "adam") == "admin"  # admins and viewers: the highest
        async with hmi.client() as client:
            nobody = await login(client, "nora", USERS["nora"][0])
            assert nobody.status_code == 403, nobody.text
            assert "nora is in none of the directory groups" in nobody.json()["detail"]["reason"]
            wrong = await login(client, "olga", "not-her-password")
            assert wrong.status_code == 401, wrong.text
            assert wrong.json()["detail"]["reason"] == "wrong user name or password"
            empty = await login(client, "olga", " ")
            assert empty.status_code == 401, empty.text
            local = await login(client, *ADMIN)  # the users file's admin, as before
            assert local.status_code == 200, local.text
            assert local.json()["user"] == {"name": ADMIN[0], "role": "admin"}
        audit = await login_audit(hmi)
        assert audit[:6] == [
            ("olga", "directory", "ok"),
            ("vera", "directory", "ok"),
            ("adam", "directory", "ok"),
            ("nora", "directory", "forbidden"),
            ("olga", "directory", "refused"),
            ("olga", "directory", "refused"),
        ]
        assert (ADMIN[0], "local", "ok") in audit[6:]
        metrics = await hmi.metrics()
        assert 'cobot_hmi_logins_total{outcome="forbidden"} 1.0' in metrics


@pytest.mark.parametrize("mode", [search_then_bind, dn_template])
async def test_injection_attempts_are_refused_not_widened(
    slapd: Slapd, place: Place, mode: Any
) -> None:
    settings = mode(slapd) | {"login_free_attempts": 1000}  # not the throttle's test
    async with hmi_with(place, **settings) as hmi:
        async with hmi.client() as client:
            for name in INJECTIONS:
                answer = await login(client, name, USERS["olga"][0])
                assert answer.status_code == 401, (name, answer.text)
            assert (await login(client, "olga", USERS["olga"][0])).status_code == 200
        audit = await login_audit(hmi)
        assert [row for row in audit if row[2] == "refused"] == [
            (name, "directory", "refused") for name in INJECTIONS
        ]


async def test_the_login_throttle_counts_directory_failures(slapd: Slapd, place: Place) -> None:
    settings = dn_template(slapd) | {"login_free_attempts": 0, "login_user_delay_max_s": 600.0}
    async with hmi_with(place, **settings) as hmi, hmi.client() as client:
        # Each failure doubles the wait (2 s, 4 s …): however slow the machine, an attempt
        # soon comes inside one.
        for _ in range(12):
            answer = await login(client, "olga", "not-her-password")
            if answer.status_code == 429:
                break
            assert answer.status_code == 401, answer.text
        assert answer.status_code == 429, answer.text
        assert int(answer.headers["retry-after"]) >= 1
        # During the wait not even the right password is asked of the directory.
        refused = await login(client, "olga", USERS["olga"][0])
        assert refused.status_code == 429, refused.text


async def test_a_group_change_takes_effect_at_the_next_login_and_at_renewal(
    slapd: Slapd, place: Place
) -> None:
    settings = dn_template(slapd) | {"ldap_role_refresh_s": 0.2}
    async with hmi_with(place, **settings) as hmi:
        async with hmi.client() as client:
            answer = await login(client, "gina", USERS["gina"][0])
            assert answer.json()["user"]["role"] == "viewer"
            token = answer.json()["token"]
        slapd.move("gina", leave=VIEWERS, join=OPERATORS)
        try:
            # Her viewer session ends once her role is read again (a refresh, with the
            # anonymous bind: the template needs no service account) …
            async with hmi.client(token) as session:

                async def ended() -> bool:
                    return (await session.get("/api/v1/auth/me")).json()["user"] is None

                await eventually_async(ended)
            # … and her next login is an operator's.
            assert await role_of(hmi, "gina") == "operator"
        finally:
            slapd.move("gina", leave=OPERATORS, join=VIEWERS)
        assert await role_of(hmi, "gina") == "viewer"


async def test_stopped_directory_refuses_its_users_while_the_local_admin_logs_in(
    slapd: Slapd, place: Place
) -> None:
    async with hmi_with(place, **search_then_bind(slapd)) as hmi:
        assert await role_of(hmi, "olga") == "operator"
        slapd.stop()
        try:
            async with hmi.client() as client:
                away = await login(client, "olga", USERS["olga"][0])
                assert away.status_code == 503, away.text
                assert away.json()["detail"]["reason"] == "directory unreachable"
                local = await login(client, *ADMIN)
                assert local.status_code == 200, local.text
            audit = await login_audit(hmi)
        finally:
            slapd.start()
        assert audit[-3:-1] == [("olga", "directory", "unreachable"), (ADMIN[0], "local", "ok")]
        # (the last row is login_audit's own admin login)
        assert await role_of(hmi, "olga") == "operator"  # back with the directory


async def test_ldaps_with_the_tests_ca(slapd: Slapd, place: Place) -> None:
    settings = dn_template(slapd) | {"ldap_url": slapd.ldaps_url, "ldap_ca_file": slapd.ca_file}
    async with hmi_with(place, **settings) as hmi:
        assert await role_of(hmi, "olga") == "operator"
        assert await role_of(hmi, "adam") == "admin"

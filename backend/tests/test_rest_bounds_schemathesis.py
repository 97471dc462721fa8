"""The REST API against its own contract (issue 37, item 10), on the real service and emulator
over loopback: integers past what SQLite binds, a body past ``max_body_bytes``, and a bounded
schemathesis run of every operation of the served OpenAPI document.

- ``offset`` of ``/events``, ``/alarms/history`` (JSON and CSV), ``/audit`` and a checkout's id
  at 2^63 were answered 500 (SQLite's ``OverflowError``): now 422 naming the parameter, and
  the bound (``api.bounds``) is in the contract as ``maximum``.
- A 2 MB body was sometimes answered with a connection reset instead of the 413 (the service
  closed with the body unread): python-requests sees the 413 twenty times in a row.
- schemathesis (an independent client, from PyPI) generates requests from the service's
  ``/openapi.json`` (valid and invalid data, logged in as an admin) and checks that no answer
  is a server error; every operation must have been called, none is skipped in silence.

The schemathesis run and python-requests are blocking: they run on a worker thread while the
service serves on the test's event loop.
"""

from __future__ import annotations

import asyncio
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import hypothesis
import pytest
import requests
import schemathesis
from schemathesis import GenerationMode
from schemathesis.checks import not_a_server_error
from schemathesis.core.failures import Failure, FailureGroup
from schemathesis.core.result import Err, Ok

from cobot_hmi.emulator.target import Target
from cobot_hmi.service.api.bounds import MAX_INTEGER
from service_support import (
    ADMIN,
    DEADLINE_S,
    OPERATOR,
    Running,
    hmi_fixture,
    running_service,
    service_settings,
)
from tls_support import TestCa

pytestmark = pytest.mark.timeout(300)

hmi = hmi_fixture()

TOO_BIG = 2**63
"""One past SQLite's largest integer (signed 64-bit)."""


# --------------------------------------------------------------------------- 2^63


def _routes(robot: str) -> list[tuple[str, str]]:
    """(path with the value, the parameter a 422 must name) of every route of the issue."""
    checkout = f"/api/v1/robots/{robot}/checkouts"
    return [
        (f"/api/v1/events?offset={TOO_BIG}", "offset"),
        (f"/api/v1/events?offset={TOO_BIG}&format=csv", "offset"),
        (f"/api/v1/alarms/history?offset={TOO_BIG}", "offset"),
        (f"/api/v1/alarms/history?offset={TOO_BIG}&format=csv", "offset"),
        (f"/api/v1/audit?offset={TOO_BIG}", "offset"),
        (f"/api/v1/audit?offset={TOO_BIG}&format=csv", "offset"),
        (f"{checkout}/{TOO_BIG}", "checkout_id"),
        (f"{checkout}/{TOO_BIG}/report.csv", "checkout_id"),
    ]


async def test_integers_past_sqlite_are_refused_naming_the_parameter(hmi: Running) -> None:
    token = await hmi.login(OPERATOR)
    robot = hmi.service.default_robot.name
    async with hmi.client(token) as client, hmi.client() as anonymous:
        for path, parameter in _routes(robot):
            answer = await client.get(path)
            assert answer.status_code == 422, (path, answer.status_code, answer.text)
            assert answer.json()["detail"]["field"] == parameter, (path, answer.text)
            assert str(MAX_INTEGER) in answer.json()["detail"]["reason"], answer.text
        # Reading needs no login by default: the refusal does not either.
        answer = await anonymous.get(f"/api/v1/events?offset={TOO_BIG}")
        assert answer.status_code == 422, answer.text
        # The bound itself is served: an empty page, no such checkout.
        for path in ("/api/v1/events", "/api/v1/alarms/history", "/api/v1/audit"):
            answer = await client.get(path, params={"offset": MAX_INTEGER})
            assert answer.status_code == 200, (path, answer.text)
            assert answer.json()["items"] == [], answer.text
        answer = await client.get(f"/api/v1/robots/{robot}/checkouts/{MAX_INTEGER}")
        assert answer.status_code == 404, answer.text


async def test_the_bounds_are_in_the_contract(hmi: Running) -> None:
    async with hmi.client() as client:
        document = (await client.get("/openapi.json")).json()
    unbounded = [
        f"{method.upper()} {path} {parameter['name']}"
        for path, operations in document["paths"].items()
        for method, operation in operations.items()
        for parameter in operation.get("parameters", [])
        for schema in _alternatives(parameter["schema"])
        if schema.get("type") == "integer" and "maximum" not in schema
    ]
    assert unbounded == []


def _alternatives(schema: dict[str, Any]) -> list[dict[str, Any]]:
    return [schema, *schema.get("anyOf", [])]


# --------------------------------------------------------------------------- a 2 MB body

BODY_BYTES = 2 * 1024 * 1024
TIMES = 20


def _post_large_bodies(url: str, token: str, verify: str | bool = True) -> list[str]:
    """What python-requests saw for each of ``TIMES`` 2 MB bodies: the status or the error."""
    seen: list[str] = []
    body = b'{"tool_do": "' + b"x" * BODY_BYTES + b'"}'
    for _ in range(TIMES):
        try:
            answer = requests.patch(
                url,
                data=body,
                headers={"Authorization": f"Bearer {token}", "Content-Type": "application/json"},
                timeout=DEADLINE_S,
                verify=verify,
            )
        except requests.RequestException as error:
            seen.append(f"{type(error).__name__}: {error}")
        else:
            seen.append(str(answer.status_code))
            assert "max_body_bytes" in answer.text, answer.text
    return seen


async def test_a_2mb_body_is_answered_413_every_time(hmi: Running) -> None:
    token = await hmi.login(OPERATOR)
    seen = await asyncio.to_thread(_post_large_bodies, f"{hmi.base_url}/api/v1/command", token)
    assert seen == ["413"] * TIMES, Counter(seen)


async def test_a_2mb_body_over_https_is_answered_413_every_time(
    target: Target, robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    """Over TLS the reset showed one time in two: the service closed with the body unread."""
    ca = TestCa.create(tmp_path / "ca")
    cert, key = tmp_path / "tls" / "cert.pem", tmp_path / "tls" / "key.pem"
    cert.parent.mkdir()
    ca.issue(cert, key, plc_host)
    settings = service_settings(
        robot_host, target.tcp_port, plc_host, tmp_path, tls_cert=cert, tls_key=key
    )
    async with running_service(settings) as running:
        url = f"https://{plc_host}:{settings.web.port}/api/v1/command"
        token = await _https_login(url.replace("/command", "/auth/login"), str(ca.ca_file))
        seen = await asyncio.to_thread(_post_large_bodies, url, token, str(ca.ca_file))
        assert running.service.settings.web.max_body_bytes < BODY_BYTES
    assert seen == ["413"] * TIMES, Counter(seen)


async def _https_login(url: str, ca_file: str) -> str:
    def login() -> str:
        answer = requests.post(
            url,
            json={"username": OPERATOR[0], "password": OPERATOR[1]},
            timeout=DEADLINE_S,
            verify=ca_file,
        )
        assert answer.status_code == 200, answer.text
        token: str = answer.json()["token"]
        return token

    return await asyncio.to_thread(login)


# --------------------------------------------------------------------------- schemathesis

EXAMPLES_PER_OPERATION = 5
"""Generated requests per operation and generation mode (valid, invalid): 56 operations, about
560 requests, 10 to 30 s on loopback on a busy machine."""
LAST = ("POST /api/v1/auth/logout",)
"""Run after every other operation: it ends the session the run is logged in with."""


@dataclass
class Run:
    calls: Counter[str] = field(default_factory=Counter)
    failures: list[str] = field(default_factory=list)


def _exercise(
    operation: Any,
    mode: GenerationMode,
    session: requests.Session,
    run: Run,
    *,
    pinned: dict[str, dict[str, Any]],
    examples: int,
) -> None:
    """``examples`` requests of ``operation``, the ``pinned`` parameters as given and the rest
    generated around them, each checked for a server error."""
    label = operation.label

    @hypothesis.settings(
        max_examples=examples,
        deadline=None,
        database=None,
        derandomize=True,  # the same requests every run: a failure is reproducible
        phases=[hypothesis.Phase.explicit, hypothesis.Phase.generate],
        suppress_health_check=list(hypothesis.HealthCheck),
    )
    @hypothesis.given(case=operation.as_strategy(generation_mode=mode, **pinned))
    def call(case: schemathesis.Case[Any]) -> None:
        response = case.call(session=session, timeout=DEADLINE_S)
        run.calls[label] += 1
        try:
            case.validate_response(response, checks=[not_a_server_error])
        except (Failure, FailureGroup) as failure:  # it says the request and the answer
            run.failures.append(f"{label} ({mode.value}, {pinned}): {failure}")

    call()


BEYOND_INT64 = 2**64


def _robot_of(operation: Any, robot: str) -> dict[str, dict[str, Any]]:
    """The robot's name pinned where the path has one (a random name only finds the 404)."""
    return {"path_parameters": {"name": robot}} if "{name}" in operation.path else {}


def _edges(operation: Any, document: dict[str, Any], robot: str) -> list[dict[str, dict[str, Any]]]:
    """An integer parameter's edges, one request each: its bounds and one past each, or past
    any 64-bit integer where it has no maximum (random generation rarely goes that far)."""
    definition = document["paths"][operation.path][operation.method.lower()]
    base = _robot_of(operation, robot)
    where = {"query": "query", "path": "path_parameters"}
    pinned: list[dict[str, dict[str, int]]] = []
    for parameter in definition.get("parameters", []):
        for schema in _alternatives(parameter["schema"]):
            if schema.get("type") != "integer" or parameter["in"] not in where:
                continue
            values = [schema["maximum"], schema["maximum"] + 1] if "maximum" in schema else []
            values += [schema["minimum"] - 1] if "minimum" in schema else []
            values += [] if "maximum" in schema else [BEYOND_INT64]
            for value in values:
                place = where[parameter["in"]]
                pinned.append({**base, place: {**base.get(place, {}), parameter["name"]: value}})
    return pinned


def _schemathesis_run(base_url: str, token: str, robot: str) -> tuple[Run, list[str], list[str]]:
    """Every operation of the served contract, each mode, and each integer parameter's edges;
    (the run, the operations, what could not be loaded or was left out)."""
    schema = schemathesis.openapi.from_url(f"{base_url}/openapi.json")
    schema.config.update(base_url=base_url)
    loaded = list(schema.get_all_operations())
    errors = [str(item.err()) for item in loaded if isinstance(item, Err)]
    operations = [item.ok() for item in loaded if isinstance(item, Ok)]
    errors += [
        f"{o.label}: skipped {o.skipped_parameters}" for o in operations if o.skipped_parameters
    ]
    errors += [f"{o.label}: body skipped" for o in operations if o.has_skipped_required_body]
    operations.sort(key=lambda operation: operation.label in LAST)
    run = Run()
    with requests.Session() as session:
        session.headers["Authorization"] = f"Bearer {token}"
        for operation in operations:
            for pinned in _edges(operation, schema.raw_schema, robot):
                _exercise(
                    operation, GenerationMode.POSITIVE, session, run, pinned=pinned, examples=1
                )
            for mode, pinned in (
                (GenerationMode.POSITIVE, _robot_of(operation, robot)),
                (GenerationMode.NEGATIVE, {}),
            ):
                try:
                    _exercise(
                        operation,
                        mode,
                        session,
                        run,
                        pinned=pinned,
                        examples=EXAMPLES_PER_OPERATION,
                    )
                except hypothesis.errors.Unsatisfiable:
                    # Nothing invalid to generate (no parameters, no body): said, not hidden.
                    assert mode is GenerationMode.NEGATIVE, operation.label
    return run, [operation.label for operation in operations], errors


async def test_schemathesis_finds_no_server_error(hmi: Running) -> None:
    token = await hmi.login(ADMIN)
    robot = hmi.service.default_robot.name
    run, operations, errors = await asyncio.to_thread(_schemathesis_run, hmi.base_url, token, robot)
    assert errors == [], errors
    assert len(operations) >= 50, operations  # the contract was read whole
    assert [label for label in operations if run.calls[label] == 0] == []  # none skipped
    assert run.failures == [], "\n\n".join(run.failures)

"""Helpers for the service tests: the emulator's target in-process, the service on uvicorn on
a free port of its own loopback address, users, login and waiting for conditions.

Everything runs over real sockets: the emulator's EtherNet/IP target on ``robot_host``, the
service's originator (on its own thread) receiving T→O on ``plc_host``, HTTP and WebSocket
on ``plc_host`` too.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import json
import os
import tempfile
from collections.abc import AsyncIterator, Generator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import pytest
import uvicorn

from cobot_hmi.composition import build_service
from cobot_hmi.emulator.faults import TargetFaults
from cobot_hmi.emulator.process_image import IdleBehaviour, ProcessImage
from cobot_hmi.emulator.static_robot import StaticRobot
from cobot_hmi.emulator.target import Target
from cobot_hmi.emulator.target_settings import TargetSettings
from cobot_hmi.service.access.users import Role, UsersFile
from cobot_hmi.service.api.app import create_app
from cobot_hmi.service.api.server import uvicorn_config
from cobot_hmi.service.runtime import Service
from cobot_hmi.settings import HmiSettings
from conftest import free_tcp_port
from waiting import eventually, eventually_async

DEADLINE_S = 30.0
"""The HTTP clients' timeout and the waits for a link (a request answered in milliseconds when
all is well; a fresh clone's run at load 30-45 saw requests time out after 10 s)."""
__all__ = ["eventually", "eventually_async"]  # (the tests import the waits from here too)
OPERATOR = ("olivia", "olivia-password")
OPERATOR_2 = ("oscar", "oscar-password")
VIEWER = ("victor", "victor-password")
ADMIN = ("ada", "ada-password-1")


class QuietServer(uvicorn.Server):
    """uvicorn without its signal handlers: the test process owns its signals."""

    @contextlib.contextmanager
    def capture_signals(self) -> Generator[None, None, None]:
        yield


@contextlib.asynccontextmanager
async def emulator(
    robot_host: str,
    robot: ProcessImage | None = None,
    *,
    tcp_port: int = 0,
    faults: TargetFaults | None = None,
) -> AsyncIterator[Target]:
    target = Target(
        TargetSettings(host=robot_host, tcp_port=tcp_port),
        robot if robot is not None else StaticRobot(IdleBehaviour.HOLD),
        faults=faults,
    )
    await target.start()
    try:
        yield target
    finally:
        await target.stop()


def service_settings(
    robot_host: str, robot_tcp_port: int, plc_host: str, state_dir: Path, **overrides: Any
) -> HmiSettings:
    settings = HmiSettings.from_keys(
        robot_host=robot_host,
        robot_tcp_port=robot_tcp_port,
        local_host=plc_host,
        host=plc_host,
        port=free_tcp_port(plc_host),
        state_dir=state_dir,
        frontend_dir=state_dir / "no-frontend",
        ws_batch_ms=50.0,
        write_timeout_ms=2000.0,
        # RPI × 128 before either side declares the connection lost: the machine is shared and
        # busy, and these tests are about the service, not about the watchdog.
        timeout_multiplier=5,
    )
    return settings.replace(**overrides)


def cell_settings(
    robots: list[tuple[str, str, int]], plc_host: str, state_dir: Path, **overrides: Any
) -> HmiSettings:
    """Settings for several robots: ``(name, host, tcp_port)`` each, first = the default."""
    _, first_host, first_port = robots[0]
    return service_settings(first_host, first_port, plc_host, state_dir).replace(
        robots=[{"name": name, "host": host, "tcp_port": port} for name, host, port in robots],
        **overrides,
    )


@functools.cache
def _test_users() -> dict[str, Any]:
    """The users file's entries of the four test users, hashed once per process (scrypt is made
    to be slow: four hashes for each service a test starts added up to minutes)."""
    with tempfile.TemporaryDirectory() as directory:
        path = Path(directory) / "users.json"
        users = UsersFile(path)
        for (name, password), role in (
            (OPERATOR, Role.OPERATOR),
            (OPERATOR_2, Role.OPERATOR),
            (VIEWER, Role.VIEWER),
            (ADMIN, Role.ADMIN),
        ):
            users.add(name, role, password)
        entries: dict[str, Any] = json.loads(path.read_text())["users"]
        return entries


def add_users(settings: HmiSettings) -> None:
    """The four test users in ``settings``' users file (beside any it holds), written as
    ``UsersFile`` writes it: whole, private, then renamed into place."""
    path = settings.web.users_path
    document = json.loads(path.read_text()) if path.exists() else {}
    document.setdefault("users", {}).update(_test_users())
    path.parent.mkdir(parents=True, exist_ok=True)
    temporary = path.with_name(f".{path.name}.test.tmp")
    fd = os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w", encoding="utf-8") as file:
        file.write(json.dumps(document, indent=2) + "\n")
    temporary.replace(path)


@dataclass
class Running:
    service: Service
    settings: HmiSettings

    @property
    def base_url(self) -> str:
        return f"http://{self.settings.web.host}:{self.settings.web.port}"

    @property
    def ws_url(self) -> str:
        return f"ws://{self.settings.web.host}:{self.settings.web.port}/api/v1/stream"

    def robot_ws_url(self, name: str) -> str:
        return f"ws://{self.settings.web.host}:{self.settings.web.port}/api/v1/robots/{name}/stream"

    def client(self, token: str | None = None) -> httpx.AsyncClient:
        headers = {"Authorization": f"Bearer {token}"} if token else {}
        return httpx.AsyncClient(base_url=self.base_url, headers=headers, timeout=DEADLINE_S)

    async def metrics(self) -> str:
        async with self.client() as client:
            return (await client.get("/metrics")).text

    async def login(self, user: tuple[str, str]) -> str:
        async with self.client() as client:
            answer = await client.post(
                "/api/v1/auth/login", json={"username": user[0], "password": user[1]}
            )
        assert answer.status_code == 200, answer.text
        token: str = answer.json()["token"]
        return token


def _has_frame(robot: Any) -> bool:
    return robot.frames.latest is not None


def hmi_fixture(**overrides: Any) -> Any:
    """A test module's ``hmi`` fixture (``hmi = hmi_fixture(...)``): the service, with the
    settings ``overrides``, against the test's ``target`` emulator (conftest)."""

    @pytest.fixture
    async def hmi(
        target: Target, robot_host: str, plc_host: str, tmp_path: Path
    ) -> AsyncIterator[Running]:
        settings = service_settings(robot_host, target.tcp_port, plc_host, tmp_path, **overrides)
        async with running_service(settings) as running:
            yield running

    return hmi


STARTUP_DEADLINE_S = 240.0
"""Until uvicorn says it started (a functional deadline with room for a loaded machine)."""


@contextlib.asynccontextmanager
async def running_service(
    settings: HmiSettings, *, wait_connected: bool = True
) -> AsyncIterator[Running]:
    """The service on uvicorn in this event loop (its originator on its own thread)."""
    await asyncio.to_thread(add_users, settings)  # scrypt: keep the emulator's loop free
    service = build_service(settings)
    server = QuietServer(
        uvicorn_config(create_app(service), settings.web, settings.tls, log_level="warning")
    )
    task = asyncio.create_task(server.serve())
    try:
        # Startup may load the OPC UA NodeSets (~10 s quiet, several times that when busy).
        await eventually(lambda: server.started or task.done(), timeout_s=STARTUP_DEADLINE_S)
        if task.done():
            await task
        running = Running(service, settings)
        if wait_connected:
            for robot in service.robots.values():
                assert await robot.link.wait_connected(DEADLINE_S), robot.name
                await eventually(functools.partial(_has_frame, robot))
        yield running
    finally:
        server.should_exit = True
        await task

"""Several robots from one service, against real emulators on loopback (issue 12).

Each robot has its own connection, hub, control and write confirmation; all share one UDP 2222
socket of the service's address. One robot lost never disturbs another's stream; the cyclic
thread that holds them all is restarted when it dies, and says so.
"""

from __future__ import annotations

import asyncio
import contextlib
import ctypes
import signal
import subprocess
import sys
from collections.abc import AsyncIterator
from pathlib import Path

import orjson
import pytest
from websockets.asyncio.client import ClientConnection, connect

from cobot_hmi.emulator.process_image import IdleBehaviour
from cobot_hmi.emulator.static_robot import StaticRobot
from cobot_hmi.scanner.originator import ConnectionState
from cobot_hmi.service.errors import UnknownRobotError
from cobot_hmi.service.runtime import Service
from cobot_hmi.service.service_settings import RobotSettings
from cobot_hmi.settings import HmiSettings
from conftest import _next_host, free_tcp_port
from service_support import (
    DEADLINE_S,
    OPERATOR,
    OPERATOR_2,
    Running,
    emulator,
    eventually,
    running_service,
)

# The machine is shared and busy: RPI × 128 before a side declares a connection lost.
_SLACK_MULTIPLIER = 5


def _settings(
    plc_host: str, state_dir: Path, robots: list[RobotSettings], **overrides: object
) -> HmiSettings:
    return HmiSettings.model_validate(
        {
            "robots": robots,
            "local_host": plc_host,
            "host": plc_host,
            "port": free_tcp_port(plc_host),
            "state_dir": state_dir,
            "frontend_dir": state_dir / "no-frontend",
            "write_timeout_ms": 3000.0,
            "timeout_multiplier": _SLACK_MULTIPLIER,
            **overrides,
        }
    )


def _robot(name: str, host: str, tcp_port: int, **changes: object) -> RobotSettings:
    return RobotSettings.model_validate(
        {"name": name, "host": host, "tcp_port": tcp_port, **changes}
    )


async def _wait_all_connected(service: Service) -> None:
    for runtime in service.robots.values():
        assert await runtime.link.wait_connected(DEADLINE_S), runtime.name
    await eventually(lambda: all(r.frames.latest is not None for r in service.robots.values()))


class StreamReader:
    """A WebSocket client of one robot's stream that keeps every message it reads."""

    def __init__(self, ws: ClientConnection) -> None:
        self.ws = ws
        self.messages: list[dict[str, object]] = []
        self.task = asyncio.create_task(self._read())

    async def _read(self) -> None:
        with contextlib.suppress(Exception):
            async for text in self.ws:
                self.messages.append(orjson.loads(text))

    def of(self, kind: str) -> list[dict[str, object]]:
        return [m for m in self.messages if m["type"] == kind]

    def seqs(self) -> list[int]:
        out: list[int] = []
        for message in self.of("frames"):
            frames = message["frames"]
            assert isinstance(frames, list)
            out.extend(int(f["seq"]) for f in frames)
        return out

    async def close(self) -> None:
        await self.ws.close()
        await self.task


@contextlib.asynccontextmanager
async def stream_of(hmi: Running, name: str) -> AsyncIterator[StreamReader]:
    url = f"ws://{hmi.settings.web.host}:{hmi.settings.web.port}/api/v1/robots/{name}/stream"
    async with connect(url, origin=f"http://{hmi.settings.web.host}:{hmi.settings.web.port}") as ws:  # type: ignore[arg-type]
        reader = StreamReader(ws)
        try:
            yield reader
        finally:
            await reader.close()


def _holder(answer: dict[str, object]) -> object:
    holder = answer["holder"]
    return holder["user"] if isinstance(holder, dict) else None


# --------------------------------------------------------------------------- two robots


async def test_two_robots_stream_with_independent_control_and_writes(
    plc_host: str, tmp_path: Path
) -> None:
    host_a, host_b = _next_host(), _next_host()
    robot_a, robot_b = StaticRobot(IdleBehaviour.HOLD), StaticRobot(IdleBehaviour.HOLD)
    async with emulator(host_a, robot_a) as target_a, emulator(host_b, robot_b) as target_b:
        settings = _settings(
            plc_host,
            tmp_path,
            [_robot("alpha", host_a, target_a.tcp_port), _robot("beta", host_b, target_b.tcp_port)],
        )
        assert [r.name for r in settings.cell.robots] == ["alpha", "beta"]
        async with running_service(settings) as hmi:
            service = hmi.service
            await _wait_all_connected(service)
            assert service.default_robot is service.robot("alpha")
            with pytest.raises(UnknownRobotError, match="known: alpha, beta"):
                service.robot("gamma")
            # Both connections share the service's one UDP socket.
            ports = {r.link.originator.io_port for r in service.robots.values()}
            assert len(ports) == 1
            port = next(iter(ports))
            assert port is not None
            assert (port.local_host, port.udp_port) == (plc_host, 2222)

            olivia, oscar = await hmi.login(OPERATOR), await hmi.login(OPERATOR_2)
            async with (
                stream_of(hmi, "alpha") as stream_a,
                stream_of(hmi, "beta") as stream_b,
                hmi.client(olivia) as first,
                hmi.client(oscar) as second,
            ):
                # Independent control: each operator holds one robot.
                taken_a = await first.post("/api/v1/robots/alpha/control/take", json={})
                assert taken_a.status_code == 200, taken_a.text
                taken_b = await second.post("/api/v1/robots/beta/control/take", json={})
                assert taken_b.status_code == 200, taken_b.text
                assert _holder(service.robot("alpha").control.status()) == OPERATOR[0]
                assert _holder(service.robot("beta").control.status()) == OPERATOR_2[0]
                # Holding alpha is no right to write beta.
                refused = await first.patch(
                    "/api/v1/robots/beta/command", json={"tool_do": {"0": True}}
                )
                assert refused.status_code == 409, refused.text
                # Each write goes to its own robot, confirmed by that robot's own frames.
                write_a = await first.patch(
                    "/api/v1/robots/alpha/command", json={"tool_do": {"1": True}}
                )
                assert write_a.status_code == 200, write_a.text
                write_b = await second.patch(
                    "/api/v1/robots/beta/command", json={"tool_do": {"4": True}}
                )
                assert write_b.status_code == 200, write_b.text
                await eventually(
                    lambda: (
                        robot_a.command_image().tool_do[1] and robot_b.command_image().tool_do[4]
                    )
                )
                assert robot_a.command_image().tool_do == (False, True, False, False, False, False)
                assert robot_b.command_image().tool_do == (False, False, False, False, True, False)
                # Both streams carry their own robot's frames, each without a hole.
                await eventually(lambda: len(stream_a.seqs()) > 20 and len(stream_b.seqs()) > 20)
                for stream, name in ((stream_a, "alpha"), (stream_b, "beta")):
                    hello = stream.of("hello")[0]
                    assert hello["robot"] == name
                    seqs = stream.seqs()
                    assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))
                    assert not stream.of("dropped")

                # The stream shows the write once it reaches the frame that confirmed it (on a
                # loaded machine the stream's newest frame can still be older than that).
                def newest(stream: StreamReader) -> dict[str, list[bool]]:
                    frames = stream.of("frames")[-1]["frames"]
                    assert isinstance(frames, list)
                    frame: dict[str, list[bool]] = frames[-1]["frame"]
                    return frame

                await eventually(lambda: newest(stream_a)["tool_do"][1] is True)
                assert newest(stream_b)["tool_do"][1] is False
                # Events carry the robot's name.
                controls = [
                    m["event"]
                    for m in stream_b.of("event")
                    if m["event"]["kind"] == "control"  # type: ignore[index]
                ]
                assert controls and all(e["robot"] == "beta" for e in controls)  # type: ignore[index]
                # Releasing one leaves the other held.
                released = await first.post("/api/v1/robots/alpha/control/release", json={})
                assert released.status_code == 200, released.text
                assert service.robot("alpha").control.holder is None
                assert _holder(service.robot("beta").control.status()) == OPERATOR_2[0]
            # Audit rows carry the robot's name and filter by it.
            for name in ("alpha", "beta"):
                page = await service.store.audit_page(100, 0, robot=name)
                assert page.total >= 2
                assert {row["robot"] for row in page.items} == {name}


def _start_emulator_process(host: str, tcp_port: int) -> subprocess.Popen[bytes]:
    return subprocess.Popen(
        [
            sys.executable,
            "-m",
            "cobot_hmi.cli",
            "emulator",
            "--host",
            host,
            "--tcp-port",
            str(tcp_port),
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )


async def test_one_robot_killed_the_other_streams_without_a_gap(
    plc_host: str, tmp_path: Path
) -> None:
    host_a, host_b = _next_host(), _next_host()
    tcp_b = free_tcp_port(host_b)
    process = _start_emulator_process(host_b, tcp_b)
    try:
        async with emulator(host_a) as target_a:
            settings = _settings(
                plc_host,
                tmp_path,
                [_robot("alpha", host_a, target_a.tcp_port), _robot("beta", host_b, tcp_b)],
            )
            async with running_service(settings, wait_connected=False) as hmi:
                service = hmi.service
                await _wait_all_connected(service)
                alpha, beta = service.robot("alpha"), service.robot("beta")
                async with stream_of(hmi, "alpha") as stream_a, stream_of(hmi, "beta") as stream_b:
                    await eventually(lambda: len(stream_a.seqs()) > 10)
                    before = await alpha.link.stats()
                    process.send_signal(signal.SIGKILL)
                    process.wait()
                    # Beta is lost (its watchdog) and keeps trying; alpha never notices.
                    await eventually(
                        lambda: beta.link.state is not ConnectionState.CONNECTED, timeout_s=30
                    )
                    await eventually(
                        lambda: any(
                            m["event"]["kind"] == "connection"  # type: ignore[index]
                            and m["event"]["state"] != "connected"  # type: ignore[index]
                            for m in stream_b.of("event")
                        )
                    )
                    shown = len(stream_a.seqs())
                    await eventually(lambda: len(stream_a.seqs()) > shown + 50, timeout_s=30)
                    after = await alpha.link.stats()
                    assert alpha.link.state is ConnectionState.CONNECTED
                    assert after.gaps == before.gaps == 0
                    assert alpha.connection.losses == 0
                    assert beta.connection.losses >= 1
                    seqs = stream_a.seqs()
                    assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))
                    assert not stream_a.of("dropped")
                    assert not [
                        m
                        for m in stream_a.of("event")
                        if m["event"]["kind"] == "connection"  # type: ignore[index]
                    ]
                    assert alpha.connection.ready() == (True, None)
                    ready, reason = beta.connection.ready()
                    assert not ready and reason
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()


async def test_a_robot_down_too_long_makes_the_service_unhealthy(
    plc_host: str, tmp_path: Path
) -> None:
    host_a, host_b = _next_host(), _next_host()
    async with emulator(host_a) as target_a:
        # Nothing listens at beta's address: it is refused (connection refused) for ever.
        settings = _settings(
            plc_host,
            tmp_path,
            [
                _robot("alpha", host_a, target_a.tcp_port),
                _robot("beta", host_b, free_tcp_port(host_b)),
            ],
            link_down_unhealthy_s=0.5,
        )
        async with running_service(settings, wait_connected=False) as hmi:
            service = hmi.service
            assert await service.robot("alpha").link.wait_connected(DEADLINE_S)
            await eventually(lambda: service.health_problems() != [])
            problems = service.health_problems()
            assert len(problems) == 1 and problems[0].startswith("robot beta: not connected")
            async with hmi.client() as client:
                health = await client.get("/healthz")
                assert health.status_code == 503
                assert any("beta" in p for p in health.json()["problems"])
                assert (await client.get("/readyz", params={"robot": "alpha"})).status_code == 200
                assert (await client.get("/readyz", params={"robot": "beta"})).status_code == 503


async def test_a_refused_robot_never_disturbs_another(plc_host: str, tmp_path: Path) -> None:
    host_a, host_b = _next_host(), _next_host()
    async with emulator(host_a) as target_a, emulator(host_b) as target_b:
        # Beta's settings name a T→O size its robot does not have: every Forward Open is
        # refused, and retried with backoff, while alpha streams.
        settings = _settings(
            plc_host,
            tmp_path,
            [
                _robot("alpha", host_a, target_a.tcp_port),
                _robot("beta", host_b, target_b.tcp_port, t2o_size=100),
            ],
        )
        async with running_service(settings, wait_connected=False) as hmi:
            service = hmi.service
            alpha, beta = service.robot("alpha"), service.robot("beta")
            assert await alpha.link.wait_connected(DEADLINE_S)
            async with stream_of(hmi, "alpha") as stream_a:
                await eventually(lambda: beta.link.state is ConnectionState.REFUSED)
                assert beta.link.reason is not None and "size" in beta.link.reason
                shown = len(stream_a.seqs())
                # Beta is refused again and again (its backoff) while alpha goes on.
                await eventually(lambda: len(stream_a.seqs()) > shown + 50, timeout_s=30)
                stats = await alpha.link.stats()
                assert stats.gaps == 0 and alpha.connection.losses == 0
                assert alpha.link.state is ConnectionState.CONNECTED
                seqs = stream_a.seqs()
                assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))
                assert not stream_a.of("dropped")
            ready, reason = beta.connection.ready()
            assert not ready and reason is not None and reason.startswith("refused")


async def test_a_dead_cyclic_thread_is_restarted_and_reported(
    plc_host: str, tmp_path: Path
) -> None:
    host_a, host_b = _next_host(), _next_host()
    async with emulator(host_a) as target_a, emulator(host_b) as target_b:
        settings = _settings(
            plc_host,
            tmp_path,
            [_robot("alpha", host_a, target_a.tcp_port), _robot("beta", host_b, target_b.tcp_port)],
        )
        async with running_service(settings) as hmi:
            service = hmi.service
            await _wait_all_connected(service)
            cyclic = service.cyclic
            assert cyclic.alive and cyclic.restarts == 0
            async with stream_of(hmi, "beta") as stream_b:
                await eventually(lambda: stream_b.of("hello"))
                # Kill the cyclic thread as a bug would: an exception it does not catch.
                thread_id = cyclic.thread_id
                assert thread_id is not None
                ctypes.pythonapi.PyThreadState_SetAsyncExc(
                    ctypes.c_ulong(thread_id), ctypes.py_object(SystemExit)
                )
                # Generous deadlines: the Forward Closes of the dead thread's connections and the
                # restart take seconds on a busy machine.
                await eventually(lambda: cyclic.restarts == 1, timeout_s=60)
                assert cyclic.last_death == "SystemExit"
                # Both robots come back on the new thread.
                await eventually(lambda: cyclic.alive, timeout_s=60)
                for runtime in service.robots.values():
                    await eventually(
                        lambda runtime=runtime: runtime.link.state is ConnectionState.CONNECTED,  # type: ignore[misc]
                        timeout_s=60,
                    )
                assert service.health_problems() == []
                reasons = [
                    str(m["event"]["reason"])  # type: ignore[index]
                    for m in stream_b.of("event")
                    if m["event"]["kind"] == "connection"  # type: ignore[index]
                ]
                assert any("cyclic I/O thread died" in r for r in reasons), reasons
            assert "cobot_hmi_cyclic_thread_restarts_total 1.0" in await hmi.metrics()

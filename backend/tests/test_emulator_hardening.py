"""The emulator holds up against what a hostile or broken client does, on loopback: more idle
TCP connections than it allows (slowloris), a stalled 65,535-byte encapsulation message, and a
web page posting to its control API (JSON only, the token, its own address only)."""

from __future__ import annotations

import asyncio
import contextlib
import resource
import socket
from collections.abc import AsyncIterator, Iterator

import httpx
import pytest

from cobot_hmi.emulator.control_api import ControlApiServer, create_control_app
from cobot_hmi.emulator.process_image import IdleBehaviour
from cobot_hmi.emulator.robot import RobotSettings, SimulatedRobot
from cobot_hmi.emulator.static_robot import StaticRobot
from cobot_hmi.emulator.target import Target
from cobot_hmi.emulator.target_settings import TargetSettings
from cobot_hmi.enip import encapsulation
from cobot_hmi.enip.encapsulation import Command
from conftest import free_tcp_port

DEADLINE_S = 60.0
"""How long a test waits for what should take a fraction of it (a busy machine)."""
IDLE_CONNECTIONS = 1_100
"""Beyond the 1,024 descriptors a default ``ulimit -n`` gives a process."""
MAX_SESSIONS = 40
TOKEN = "test-token-0f3c"


async def eventually(check: object, what: str) -> None:
    assert callable(check)
    loop = asyncio.get_running_loop()
    end = loop.time() + DEADLINE_S
    while not check():
        assert loop.time() < end, f"{what}: not reached in {DEADLINE_S} s"
        await asyncio.sleep(0.02)


@pytest.fixture
def enough_descriptors() -> Iterator[None]:
    """Room for the idle connections' both ends in this process (the test holds the clients,
    the emulator the accepted sockets)."""
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    needed = 2 * IDLE_CONNECTIONS + 512
    if hard != resource.RLIM_INFINITY and hard < needed:
        pytest.skip(f"the hard descriptor limit {hard} is below {needed}")
    resource.setrlimit(resource.RLIMIT_NOFILE, (max(soft, needed), hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_NOFILE, (soft, hard))


@contextlib.asynccontextmanager
async def running_target(robot_host: str, **settings: object) -> AsyncIterator[Target]:
    target = Target(
        TargetSettings(host=robot_host, tcp_port=0, **settings),  # type: ignore[arg-type]
        StaticRobot(IdleBehaviour.CLEAR),
    )
    await target.start()
    try:
        yield target
    finally:
        await target.stop()


async def list_identity(host: str, port: int) -> bytes:
    """A whole TCP exchange as a real client makes it; raises if the target closes on us."""
    reader, writer = await asyncio.open_connection(host, port)
    try:
        writer.write(encapsulation.encode(Command.LIST_IDENTITY, context=b"realcli!"))
        await writer.drain()
        head = await reader.readexactly(encapsulation.HEADER_SIZE)
        header = encapsulation.decode_header(head)
        return head + await reader.readexactly(header.length)
    finally:
        writer.close()
        with contextlib.suppress(ConnectionError):
            await writer.wait_closed()


async def test_idle_connections_beyond_the_bound_are_refused_and_a_real_client_gets_in(
    robot_host: str, plc_host: str, enough_descriptors: None
) -> None:
    async with running_target(
        robot_host, max_tcp_sessions=MAX_SESSIONS, incomplete_message_timeout_s=3.0
    ) as target:
        loop = asyncio.get_running_loop()
        idle: list[socket.socket] = []
        counters = target.counters
        try:
            for _ in range(IDLE_CONNECTIONS):  # connect, then never send a byte
                sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
                idle.append(sock)
                sock.setblocking(False)
                sock.bind((plc_host, 0))
                await loop.sock_connect(sock, (robot_host, target.tcp_port))

            def all_accepted() -> bool:
                return (
                    counters.tcp_connections_open
                    + counters.tcp_sessions_refused
                    + counters.tcp_sessions_timed_out
                    == IDLE_CONNECTIONS
                )

            await eventually(all_accepted, "every connection accepted")
            # The bound held the whole time; the rest were refused (or, on a machine so slow
            # that the flood outlasted the timeout, dropped for sending nothing) and counted.
            assert counters.tcp_connections_peak <= MAX_SESSIONS
            assert counters.tcp_sessions_refused > 0
            # A real client, meanwhile: it gets in once the idle connections that hold the
            # places have been dropped for sending nothing (incomplete_message_timeout_s).
            end = loop.time() + DEADLINE_S
            while True:
                try:
                    reply = await list_identity(robot_host, target.tcp_port)
                    break
                except (ConnectionError, asyncio.IncompleteReadError):
                    assert loop.time() < end, "the real client never got in"
                    await asyncio.sleep(0.1)
            message = encapsulation.decode(reply)
            assert message.header.command == Command.LIST_IDENTITY
            assert message.header.context == b"realcli!"
            assert counters.tcp_sessions_timed_out >= 1
            assert counters.tcp_connections_peak <= MAX_SESSIONS
        finally:
            for sock in idle:
                sock.close()
        await eventually(lambda: counters.tcp_connections_open == 0, "every session closed")


async def test_a_stalled_partial_message_is_dropped_after_the_timeout(robot_host: str) -> None:
    async with running_target(robot_host, incomplete_message_timeout_s=0.5) as target:
        reader, writer = await asyncio.open_connection(robot_host, target.tcp_port)
        try:
            # A header announcing the largest message, then a little of it, then nothing.
            header = encapsulation.HEADER.pack(
                Command.REGISTER_SESSION, encapsulation.MAX_DATA_SIZE, 0, 0, bytes(8), 0
            )
            writer.write(header + bytes(1000))
            await writer.drain()
            # The target drops the connection: end of stream (or a reset) instead of a reply.
            with contextlib.suppress(ConnectionError):
                assert await asyncio.wait_for(reader.read(), DEADLINE_S) == b""
        finally:
            writer.close()
            with contextlib.suppress(ConnectionError):
                await writer.wait_closed()
        assert target.counters.tcp_sessions_timed_out == 1
        await eventually(lambda: target.counters.tcp_connections_open == 0, "session closed")


async def test_a_client_that_never_reads_its_replies_is_dropped(robot_host: str) -> None:
    async with running_target(robot_host, incomplete_message_timeout_s=0.5) as target:
        sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)  # fills fast
        sock.setblocking(False)
        loop = asyncio.get_running_loop()
        try:
            await loop.sock_connect(sock, (robot_host, target.tcp_port))
            requests = encapsulation.encode(Command.LIST_IDENTITY) * 256
            pending = b""
            end = loop.time() + DEADLINE_S
            # Ask and ask (whole messages: what a send leaves goes first next time), never
            # read: the replies back up until the target gives up on us.
            while target.counters.tcp_sessions_timed_out == 0:
                assert loop.time() < end, "the target kept a client that never reads"
                pending = pending or requests
                with contextlib.suppress(BlockingIOError):
                    pending = pending[sock.send(pending) :]
                await asyncio.sleep(0.001)
            assert target.counters.encapsulation_malformed == 0  # the stream stayed whole
        except ConnectionError:
            pass  # dropped while we were still sending: what the test waits for
        finally:
            sock.close()
        await eventually(lambda: target.counters.tcp_sessions_timed_out == 1, "counted")
        await eventually(lambda: target.counters.tcp_connections_open == 0, "session closed")


async def test_a_registered_session_may_idle_and_a_slow_whole_message_is_answered(
    robot_host: str,
) -> None:
    async with running_target(robot_host, incomplete_message_timeout_s=0.3) as target:
        reader, writer = await asyncio.open_connection(robot_host, target.tcp_port)
        try:
            writer.write(
                encapsulation.encode(
                    Command.REGISTER_SESSION, encapsulation.encode_register_session()
                )
            )
            head = await asyncio.wait_for(reader.readexactly(28), DEADLINE_S)
            handle = encapsulation.decode_header(head).session
            assert handle
            # Silent for several timeouts: a registered session (an originator's, beside its
            # class 1 connection) is not a stalled message. Waiting longer only makes it surer.
            await asyncio.sleep(1.5)
            writer.write(encapsulation.encode(Command.LIST_IDENTITY, session=handle))
            head = await asyncio.wait_for(reader.readexactly(encapsulation.HEADER_SIZE), DEADLINE_S)
            assert encapsulation.decode_header(head).command == Command.LIST_IDENTITY
        finally:
            writer.close()
            with contextlib.suppress(ConnectionError):
                await writer.wait_closed()
        assert target.counters.tcp_sessions_timed_out == 0


async def test_a_registered_session_silent_past_the_inactivity_timeout_is_closed(
    robot_host: str,
) -> None:
    async with running_target(robot_host, session_inactivity_timeout_s=0.5) as target:
        reader, writer = await asyncio.open_connection(robot_host, target.tcp_port)
        try:
            writer.write(
                encapsulation.encode(
                    Command.REGISTER_SESSION, encapsulation.encode_register_session()
                )
            )
            head = await asyncio.wait_for(reader.readexactly(28), DEADLINE_S)
            assert encapsulation.decode_header(head).session
            # Nothing more: the target closes the session (a clean end of stream).
            assert await asyncio.wait_for(reader.read(), DEADLINE_S) == b""
        finally:
            writer.close()
            with contextlib.suppress(ConnectionError):
                await writer.wait_closed()
        assert target.counters.tcp_sessions_inactive == 1
        assert target.counters.tcp_sessions_timed_out == 0
        await eventually(lambda: target.counters.tcp_connections_open == 0, "session closed")


async def test_a_connection_caught_in_its_accepting_by_stop_is_closed(robot_host: str) -> None:
    """Wherever ``stop()`` catches a connection on its way in (in the kernel's queue, accepted
    but without its transport, with a transport but before its session task runs), ``stop()``
    closes it: the client sees the end of the stream, nothing is left open in the target (a
    session the target answers only after ``stop()`` would hold its socket until the loop ends).
    Each number of loop turns between connecting and stopping is one such point."""
    for turns in range(12):
        target = Target(
            TargetSettings(
                host=robot_host, tcp_port=0, incomplete_message_timeout_s=10 * DEADLINE_S
            ),
            StaticRobot(IdleBehaviour.CLEAR),
        )
        await target.start()
        client = socket.create_connection((robot_host, target.tcp_port))
        try:
            for _ in range(turns):
                await asyncio.sleep(0)
            await target.stop()
            client.settimeout(DEADLINE_S)
            with contextlib.suppress(ConnectionResetError):  # still in the kernel's queue
                assert await asyncio.to_thread(client.recv, 1) == b"", f"after {turns} turns"
        finally:
            client.close()
        assert target.counters.tcp_connections_open == 0, f"after {turns} turns"


# ------------------------------------------------------------------------------ control API


@contextlib.asynccontextmanager
async def control_api(
    robot_host: str, token: str | None, allowed_hosts: tuple[str, ...] = ()
) -> AsyncIterator[httpx.AsyncClient]:
    robot = SimulatedRobot(RobotSettings())
    async with running_target(robot_host) as target:
        server = ControlApiServer(
            create_control_app(robot, target, token=token, allowed_hosts=allowed_hosts),
            robot_host,
            free_tcp_port(robot_host),
        )
        await server.start()
        try:
            async with httpx.AsyncClient(base_url=f"http://{robot_host}:{server.port}") as api:
                yield api
        finally:
            await server.stop()


def robot_phase(status: httpx.Response) -> str:
    assert status.status_code == 200, status.text
    phase = status.json()["robot"]["phase"]
    assert isinstance(phase, str)
    return phase


async def test_control_api_refuses_what_a_web_page_can_send_without_a_preflight(
    robot_host: str,
) -> None:
    async with control_api(robot_host, None) as api:
        # A cross-site <form enctype="text/plain">, an urlencoded form, a no-cors fetch with no
        # body: none may press e-stop or inject a fault.
        for path, headers, body in (
            ("/estop", {"content-type": "text/plain"}, b'{"": ""}'),
            ("/estop", {}, b""),
            ("/faults", {"content-type": "application/x-www-form-urlencoded"}, b"t2o_silent=1"),
            ("/faults", {"content-type": "multipart/form-data; boundary=x"}, b"--x--"),
        ):
            answer = await api.post(path, content=body, headers=headers)
            assert answer.status_code == 415, (path, headers, answer.text)
            assert "JSON only" in answer.json()["detail"]["reason"]
        status = await api.get("/status")
        assert robot_phase(status) != "emergency_stop"
        assert status.json()["faults"]["t2o_silent"] is False
        # JSON (with a charset, too) is served.
        answer = await api.post(
            "/estop", content=b"{}", headers={"content-type": "application/json; charset=utf-8"}
        )
        assert answer.status_code == 200, answer.text
        assert robot_phase(await api.get("/status")) == "emergency_stop"
        counters = (await api.get("/status")).json()["target_counters"]
        for name in ("tcp_sessions_refused", "tcp_sessions_timed_out", "udp_list_identity"):
            assert counters[name] == 0


async def test_control_api_token_is_required_when_set(robot_host: str) -> None:
    async with control_api(robot_host, TOKEN) as api:
        answer = await api.get("/status")
        assert answer.status_code == 401
        assert answer.headers["www-authenticate"] == "Bearer"
        answer = await api.post("/estop", json={})
        assert answer.status_code == 401
        answer = await api.post("/estop", json={}, headers={"authorization": "Bearer nope"})
        assert answer.status_code == 403
        answer = await api.get("/status", headers={"authorization": f"Basic {TOKEN}"})
        assert answer.status_code == 401
        good = {"authorization": f"Bearer {TOKEN}"}
        assert robot_phase(await api.get("/status", headers=good)) != "emergency_stop"
        answer = await api.post("/estop", json={}, headers=good)
        assert answer.status_code == 200, answer.text
        assert robot_phase(await api.get("/status", headers=good)) == "emergency_stop"
        # The token does not lift the JSON-only rule.
        answer = await api.post(
            "/reset", content=b"{}", headers={**good, "content-type": "text/plain"}
        )
        assert answer.status_code == 415


async def test_control_api_listens_on_the_emulators_address_only(
    robot_host: str, plc_host: str
) -> None:
    async with control_api(robot_host, None) as api:
        port = api.base_url.port
        assert port is not None
        assert (await api.get("/status")).status_code == 200
        # The same port on another address of this machine: nobody there.
        with pytest.raises(ConnectionRefusedError):
            await asyncio.open_connection(plc_host, port)


async def test_control_api_refuses_a_foreign_host_name(robot_host: str) -> None:
    # DNS rebinding: a page's own name re-pointed at the emulator sends that name as Host.
    async with control_api(robot_host, None, ("emulator",)) as api:
        port = api.base_url.port
        for host in (f"evil.example:{port}", "evil.example", f"localhost.evil.example:{port}"):
            answer = await api.post("/estop", json={}, headers={"host": host})
            assert answer.status_code == 400, (host, answer.text)
            assert "not served here" in answer.json()["detail"]["reason"]
            assert (await api.get("/status", headers={"host": host})).status_code == 400
        assert robot_phase(await api.get("/status")) != "emergency_stop"
        for host in (f"localhost:{port}", f"EMULATOR:{port}", f"[::1]:{port}", robot_host):
            answer = await api.get("/status", headers={"host": host})
            assert answer.status_code == 200, (host, answer.text)


def test_an_empty_token_is_refused() -> None:
    robot = SimulatedRobot(RobotSettings())
    target = Target(TargetSettings(tcp_port=0), StaticRobot(IdleBehaviour.CLEAR))
    with pytest.raises(ValueError, match="empty"):
        create_control_app(robot, target, token="  ")

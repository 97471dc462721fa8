"""``WS /api/v1/stream`` against the emulator over real sockets: hello, batched frames, rates
(server-side decimation), status and events, a slow and a stalled client next to a fast one,
and control released when its holder's stream closes. Every message any test receives is
validated against the contract's model (``service.api.models.StreamMessage``)."""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import socket
import time
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import orjson
import pytest
from websockets.asyncio.client import ClientConnection, connect
from websockets.exceptions import ConnectionClosed

from cobot_hmi.emulator.robot import RobotSettings, SimulatedRobot
from cobot_hmi.emulator.target import Target
from cobot_hmi.service.api.models import STREAM_MESSAGE
from conftest import _next_host as next_host
from service_support import (
    OPERATOR,
    Running,
    emulator,
    eventually,
    hmi_fixture,
    running_service,
    service_settings,
)

pytestmark = pytest.mark.timeout(120)


@pytest.fixture
async def target(robot_host: str) -> AsyncIterator[Target]:
    async with emulator(robot_host) as target:
        yield target


hmi = hmi_fixture(
    ws_queue_frames=20,
    # Stalled: one send stuck this long. A slow reader drains a send (at most 20 frames, ~54 kB)
    # in about half a second, a client that stopped reading never does. The slack is for a busy
    # machine: the slow reader shares this process's event loop with the service, and a loaded
    # run starved it past 2 s (both clients were cut off as stalled).
    ws_stall_timeout_s=6.0,
    status_interval_s=0.5,
)


class Recorder:
    """Reads a stream (optionally slowly) and keeps every message."""

    def __init__(self, connection: ClientConnection, delay_s: float = 0.0) -> None:
        self.connection = connection
        self.delay_s = delay_s
        self.messages: list[Any] = []
        self.invalid: list[str] = []
        """Messages that do not match ``models.StreamMessage`` (the frames' model is built from
        the layout; the hot path never validates, this does)."""
        self.closed: ConnectionClosed | None = None
        self.task = asyncio.create_task(self._read())

    async def _read(self) -> None:
        try:
            async for text in self.connection:
                message = orjson.loads(text)
                self.messages.append(message)
                try:
                    STREAM_MESSAGE.validate_python(message)
                except ValueError as error:
                    self.invalid.append(f"{str(message)[:200]}: {error}")
                if self.delay_s:
                    await asyncio.sleep(self.delay_s)
        except ConnectionClosed as closed:
            self.closed = closed

    def of(self, kind: str) -> list[Any]:
        return [m for m in self.messages if m["type"] == kind]

    @property
    def frames(self) -> list[Any]:
        return [f for m in self.of("frames") for f in m["frames"]]

    async def close(self) -> None:
        await self.connection.close()
        with contextlib.suppress(asyncio.CancelledError):
            await asyncio.wait_for(self.task, 5)


@contextlib.asynccontextmanager
async def recorder(url: str, delay_s: float = 0.0, **options: Any) -> AsyncIterator[Recorder]:
    async with connect(url, **options) as connection:
        reading = Recorder(connection, delay_s)
        try:
            yield reading
        finally:
            await reading.close()
        assert not reading.invalid, reading.invalid[:3]


def receive_buffer_socket(host: str, port: int, size: int) -> socket.socket:
    """A connected TCP socket with a fixed receive buffer (no autotuning up to megabytes),
    so that a client that lags behind shows within seconds."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, size)
    sock.connect((host, port))
    return sock


async def cut_off(sock: socket.socket) -> bool:
    """Whether the server closed or reset ``sock`` (read what the kernel still holds first)."""
    loop = asyncio.get_running_loop()
    try:
        for _ in range(10_000):
            if not await asyncio.wait_for(loop.sock_recv(sock, 65536), 5):
                return True
    except ConnectionResetError:
        return True
    return False


def assert_decimated(
    every: list[dict[str, Any]], decimated: list[dict[str, Any]], period_s: float
) -> None:
    """``decimated`` is ``every`` decimated to one frame per ``period_s`` by the frames' own
    receive times (the hub's rule: a frame is due from a quarter period early, dues advance by
    whole periods), whatever the machine's load did to when they arrived:

    - at most the asked rate: the k-th frame after the first is at least (k − ¼) periods later;
    - none skipped when due: between two decimated frames no frame of ``every`` came a whole
      period or more after the first of them.
    """
    times = {f["seq"]: f["t"] for f in every}
    seqs = [f["seq"] for f in decimated if f["seq"] in times]
    assert len(seqs) >= 5 and seqs == sorted(set(seqs)), seqs
    assert all(f["t"] == times[f["seq"]] for f in decimated if f["seq"] in times)
    slack_s = 1e-6  # the times are whole microseconds on the wire
    first = times[seqs[0]]
    for k, seq in enumerate(seqs):
        assert times[seq] - first >= (k - 0.25) * period_s - slack_s, (k, seq)
    for a, b in itertools.pairwise(seqs):
        late = [
            s for s in range(a + 1, b) if s in times and times[s] - times[a] > period_s + slack_s
        ]
        assert not late, (a, b, late)


async def test_hello_batches_rates_status(hmi: Running) -> None:
    async with (
        recorder(hmi.ws_url) as full,
        recorder(hmi.ws_url + "?rate=10") as decimated,
    ):
        await eventually(lambda: len(full.frames) >= 150 and len(full.of("status")) >= 1)
    hello = full.messages[0]
    assert hello["type"] == "hello"
    assert hello["layout_version"] == 1
    assert hello["connection"]["state"] == "connected"
    assert hello["control"] == {"holder": None}
    assert hello["rate_hz"] is None
    assert decimated.messages[0]["rate_hz"] == 10.0
    seqs = [f["seq"] for f in full.frames]
    assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))  # every frame, in order
    assert len(full.frames) / len(full.of("frames")) > 1.5  # batched: several per message
    first = full.frames[0]
    assert set(first) == {"seq", "t", "t2o_sequence", "frame"}
    # The wire's own numbers rise with the frames (the robot's, one per T→O packet).
    wires = [f["t2o_sequence"] for f in full.frames]
    assert all(0 < (b - a) & 0xFFFF_FFFF < 0x8000_0000 for a, b in itertools.pairwise(wires))
    assert first["frame"]["robot_state_name"] == "STANDALONE_STANDBY"
    assert not full.of("dropped")
    assert_decimated(full.frames, decimated.frames, period_s=0.1)
    assert not decimated.of("dropped")
    status = full.of("status")[0]
    assert status["connection"]["state"] == "connected"
    metrics = await hmi.metrics()
    assert "cobot_hmi_ws_clients 0.0" in metrics or "cobot_hmi_ws_clients" in metrics


async def test_bad_rate_and_login_required(
    hmi: Running, target: Target, robot_host: str, tmp_path: Path
) -> None:
    async with connect(hmi.ws_url + "?rate=-3") as connection:
        with pytest.raises(ConnectionClosed) as closed:
            await connection.recv()
    assert closed.value.rcvd is not None
    assert closed.value.rcvd.code == 4400
    assert "rate" in closed.value.rcvd.reason
    settings = service_settings(
        robot_host,
        target.tcp_port,
        next_host(),
        tmp_path / "b",
        view_requires_login=True,
        input_only=True,  # the first service owns the outputs already
    )
    async with running_service(settings) as locked:
        async with connect(locked.ws_url) as connection:
            with pytest.raises(ConnectionClosed) as closed:
                await connection.recv()
        assert closed.value.rcvd is not None
        assert closed.value.rcvd.code == 4401
        token = await locked.login(OPERATOR)
        async with connect(locked.ws_url + f"?token={token}") as connection:
            assert orjson.loads(await connection.recv())["type"] == "hello"


async def raw_stream(host: str, port: int, receive_buffer_bytes: int) -> socket.socket:
    """A WebSocket opened by hand (handshake only): the test decides how it is read."""
    loop = asyncio.get_running_loop()
    sock = receive_buffer_socket(host, port, receive_buffer_bytes)
    sock.setblocking(False)
    await loop.sock_sendall(
        sock,
        (
            f"GET /api/v1/stream HTTP/1.1\r\nHost: {host}:{port}\r\nUpgrade: websocket\r\n"
            "Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
            "Sec-WebSocket-Version: 13\r\n\r\n"
        ).encode(),
    )
    head = b""
    while b"\r\n\r\n" not in head:  # byte by byte: nothing after the headers is consumed
        head += await loop.sock_recv(sock, 1)
    assert head.startswith(b"HTTP/1.1 101"), head
    return sock


def ws_text_messages(buffer: bytearray) -> list[Any]:
    """Take the complete server frames (unmasked, unfragmented) off ``buffer``; their JSON."""
    messages = []
    while len(buffer) >= 2:
        opcode, length, start = buffer[0] & 0x0F, buffer[1] & 0x7F, 2
        if length == 126:
            length, start = int.from_bytes(buffer[2:4], "big"), 4
        elif length == 127:
            length, start = int.from_bytes(buffer[2:10], "big"), 10
        if len(buffer) < start + length:
            break
        payload = bytes(buffer[start : start + length])
        del buffer[: start + length]
        if opcode == 1:
            messages.append(orjson.loads(payload))
    return messages


class SlowReader:
    """Reads a raw stream at a steady ``bytes_per_s``, below what the server sends at full rate:
    it keeps reading (it is not stalled) but falls further and further behind."""

    def __init__(self, sock: socket.socket, bytes_per_s: int) -> None:
        self.sock = sock
        self.bytes_per_s = bytes_per_s
        self.messages: list[Any] = []
        self.task = asyncio.create_task(self._read())

    async def _read(self) -> None:
        loop = asyncio.get_running_loop()
        buffer = bytearray()
        chunk = self.bytes_per_s // 50
        while True:
            data = await loop.sock_recv(self.sock, chunk)
            if not data:
                return
            buffer += data
            self.messages.extend(ws_text_messages(buffer))
            await asyncio.sleep(0.02)

    def of(self, kind: str) -> list[Any]:
        return [m for m in self.messages if m["type"] == kind]

    async def stop(self) -> None:
        self.task.cancel()
        with contextlib.suppress(asyncio.CancelledError, OSError):
            await self.task


async def test_slow_and_stalled_clients_do_not_hurt_a_fast_one(hmi: Running) -> None:
    service = hmi.service
    host, port = hmi.settings.web.host, hmi.settings.web.port
    # Full rate is ~270 kB/s of JSON (100 frames/s). The stalled client never reads after its
    # handshake; the slow one reads 100 kB/s, steadily.
    stalled = await raw_stream(host, port, 4096)
    slow_socket = await raw_stream(host, port, 16 * 1024)
    slow = SlowReader(slow_socket, 100_000)
    try:
        async with recorder(hmi.ws_url) as fast:
            await eventually(lambda: service.hub.stalled_disconnects >= 1, timeout_s=60)
            await eventually(lambda: len(slow.of("dropped")) >= 2, timeout_s=60)
            # The stalled one leaves once its cut connection's disconnect comes back round (a few
            # turns of a busy loop after the count); the slow one is still there.
            await eventually(
                lambda: all(c.closed_reason is None for c in service.hub.clients), timeout_s=60
            )
            assert len(service.hub.clients) == 2
            fast_count = len(fast.frames)
            await eventually(lambda: len(fast.frames) > fast_count + 50)
        await slow.stop()
        # The fast client lost nothing and was never told of a drop.
        seqs = [f["seq"] for f in fast.frames]
        assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))
        assert not fast.of("dropped")
        # The slow one lost old frames and was told exactly how many, before the next frames.
        missing = told = 0
        last_seq: int | None = None
        for message in slow.messages:
            if message["type"] == "dropped":
                told += message["count"]
            elif message["type"] == "frames":
                first = message["frames"][0]["seq"]
                if last_seq is not None:
                    missing += first - last_seq - 1
                last_seq = message["frames"][-1]["seq"]
        assert told > 0
        assert missing == told
        # The stalled one was cut off: its socket is reset or closed.
        assert await cut_off(stalled)
    finally:
        await slow.stop()
        stalled.close()
        slow_socket.close()
    # Nothing of this reached the cyclic connection or the broadcast loop.
    assert service.link.state.value == "connected"
    assert service.default_robot.intervals.frames_lost == 0
    metrics = await hmi.metrics()
    assert 'cobot_hmi_ws_stalled_disconnects_total{robot="robot"} 1.0' in metrics
    assert 'cobot_hmi_ws_dropped_frames_total{robot="robot"} 0.0' not in metrics


async def test_events_and_holder_disconnect_release_control(hmi: Running) -> None:
    token = await hmi.login(OPERATOR)
    async with recorder(hmi.ws_url) as watcher:
        holder_stream = await connect(
            hmi.ws_url, additional_headers={"Authorization": f"Bearer {token}"}
        )
        try:
            assert orjson.loads(await holder_stream.recv())["type"] == "hello"
            async with hmi.client(token) as client:
                assert (await client.post("/api/v1/control/take")).status_code == 200
                write = await client.patch("/api/v1/command", json={"tool_do": {"2": True}})
                assert write.status_code == 200
        finally:
            await holder_stream.close()
        await eventually(lambda: hmi.service.control.holder is None)
        await eventually(lambda: len(watcher.of("event")) >= 3)
    events = [m["event"] for m in watcher.of("event")]
    control = [e for e in events if e["kind"] == "control"]
    assert control[0]["holder"]["user"] == OPERATOR[0]
    assert control[-1] == {
        "kind": "control",
        "time": control[-1]["time"],
        "robot": "robot",
        "holder": None,
        "reason": "holder disconnected",
        "text": "Control free, nobody holds it: holder disconnected",
    }
    writes = [e for e in events if e["kind"] == "write"]
    assert writes[0]["fields"] == ["tool_do.2"]
    assert writes[0]["outcome"] == "confirmed"
    assert hmi.service.link.run is False


async def test_robot_state_and_flag_events_from_the_simulated_robot(
    robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    robot = SimulatedRobot(RobotSettings(autostart_program=False))
    async with emulator(robot_host, robot) as target:
        settings = service_settings(robot_host, target.tcp_port, plc_host, tmp_path)
        async with running_service(settings) as hmi, recorder(hmi.ws_url) as stream:
            await eventually(
                lambda: (
                    hmi.service.default_robot.frames.latest is not None
                    and hmi.service.default_robot.frames.latest[2].robot_state == 13
                )  # STANDALONE_STANDBY
            )
            robot.estop(time.time())

            def seen(kind: str, **fields: object) -> bool:
                return any(
                    m["event"]["kind"] == kind
                    and all(m["event"].get(k) == v for k, v in fields.items())
                    for m in stream.of("event")
                )

            await eventually(lambda: seen("robot_state", to_name="EMERGENCY_STOP"))
            await eventually(lambda: seen("flag", flag="emergency_stopped", value=True))
            await eventually(lambda: seen("flag", flag="servo_on", value=False))
            robot.reset(time.time())
            await eventually(lambda: seen("flag", flag="emergency_stopped", value=False))
            await hmi.service.store.flush_events()
            page = await hmi.service.store.events_page("flag", 20, 0)
            flags = {(i["flag"], i["value"]) for i in page.items}
            assert ("emergency_stopped", True) in flags
            assert ("emergency_stopped", False) in flags

"""``WS /api/v1/robots/{name}/stream`` subscriptions against the emulator over real sockets
(issue 38, item 12): a client sends ``subscribe`` with the fields it shows and the rate it draws
at, and receives only those fields at that rate; a bad subscription is refused with 4400 and
why; permessage-deflate is negotiated with a client that offers it. The client is the
``websockets`` library's, which checks nothing of the service's for it."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator
from typing import Any

import orjson
import pytest
from websockets.asyncio.client import ClientConnection, connect
from websockets.exceptions import ConnectionClosed

from cobot_hmi.emulator.target import Target
from cobot_hmi.service.api.models import STREAM_MESSAGE
from service_support import Running, emulator, eventually, hmi_fixture

pytestmark = pytest.mark.timeout(120)


@pytest.fixture
async def target(robot_host: str) -> AsyncIterator[Target]:
    async with emulator(robot_host) as target:
        yield target


hmi = hmi_fixture(status_interval_s=0.5)


class Reader:
    """Every message of a stream, each checked against the contract's models."""

    def __init__(self, connection: ClientConnection) -> None:
        self.connection = connection
        self.messages: list[Any] = []
        self.invalid: list[str] = []
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
        except ConnectionClosed as closed:
            self.closed = closed

    def after(self, kind: str) -> list[Any]:
        """The messages after the first of ``kind`` (an empty list before it came)."""
        for i, message in enumerate(self.messages):
            if message["type"] == kind:
                return self.messages[i + 1 :]
        return []

    def frames_after_subscribed(self) -> list[Any]:
        return [f for m in self.after("subscribed") if m["type"] == "frames" for f in m["frames"]]


@contextlib.asynccontextmanager
async def reader(url: str, **options: Any) -> AsyncIterator[Reader]:
    async with connect(url, **options) as connection:
        reading = Reader(connection)
        try:
            yield reading
        finally:
            await connection.close()
            with contextlib.suppress(asyncio.CancelledError):
                await asyncio.wait_for(reading.task, 5)
        assert not reading.invalid, reading.invalid[:3]


async def test_a_subscription_sends_only_the_asked_fields_at_the_asked_rate(hmi: Running) -> None:
    url = hmi.robot_ws_url("robot")
    async with reader(url) as full, reader(url) as phone, reader(url) as same:
        await phone.connection.send(
            orjson.dumps({"type": "subscribe", "fields": ["servo_on", "robot_state"], "rate_hz": 5})
        )
        # Another client asking the same in another order: the same group, the same answer.
        await same.connection.send(
            orjson.dumps({"type": "subscribe", "fields": ["robot_state", "servo_on"], "rate_hz": 5})
        )
        await eventually(
            lambda: (
                len(phone.frames_after_subscribed()) >= 15
                and len(same.frames_after_subscribed()) >= 15
            ),
            timeout_s=60,
        )
        robot = hmi.service.robot("robot")
        assert len(robot.hub._groups) == 2  # every field, and the two phones' one group
    subscribed = next(m for m in phone.messages if m["type"] == "subscribed")
    assert subscribed == {"type": "subscribed", "fields": ["robot_state", "servo_on"], "rate_hz": 5}
    frames = phone.frames_after_subscribed()
    for item in frames:
        assert set(item["frame"]) == {"robot_state", "robot_state_name", "servo_on"}, item
    # At most the asked rate, by the frames' own receive times (due from a quarter period early).
    times = [f["t"] for f in frames]
    for k, t in enumerate(times):
        assert t - times[0] >= (k - 0.25) * 0.2 - 1e-6, (k, times)
    # And about it: not far below either (the emulator sends 100 frames/s).
    assert (times[-1] - times[0]) / (len(times) - 1) < 0.3
    # The client that asked nothing still gets every field of every frame.
    whole = [f for m in full.messages if m["type"] == "frames" for f in m["frames"]]
    assert len(whole[-1]["frame"]) > 20
    seqs = [f["seq"] for f in whole]
    assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))


async def test_a_subscription_back_to_every_field(hmi: Running) -> None:
    async with reader(hmi.robot_ws_url("robot")) as client:
        await client.connection.send(
            orjson.dumps({"type": "subscribe", "fields": ["tool_di"], "rate_hz": 10})
        )
        await eventually(lambda: len(client.frames_after_subscribed()) >= 3)
        await client.connection.send(orjson.dumps({"type": "subscribe", "fields": None}))

        def after_last_ack() -> list[Any]:
            acks = [i for i, m in enumerate(client.messages) if m["type"] == "subscribed"]
            if len(acks) < 2:
                return []
            rest = client.messages[acks[-1] + 1 :]
            return [f for m in rest if m["type"] == "frames" for f in m["frames"]]

        await eventually(lambda: len(after_last_ack()) >= 10)
    narrow = client.frames_after_subscribed()
    assert set(narrow[0]["frame"]) == {"tool_di"}
    acks = [m for m in client.messages if m["type"] == "subscribed"]
    assert acks[-1] == {"type": "subscribed", "fields": None, "rate_hz": None}
    assert all(len(f["frame"]) > 20 for f in after_last_ack())


async def read_until_closed(connection: ClientConnection) -> None:
    """Read (frames may come before the close) until the service closes the connection; a
    service that never does fails the test (TimeoutError) instead of hanging it."""
    async with asyncio.timeout(30):
        while True:
            await connection.recv()


@pytest.mark.parametrize(
    ("message", "why"),
    [
        (b'{"type": "subscribe", "fields": ["joint_position", "warp_drive"]}', "warp_drive"),
        (b'{"type": "subscribe", "rate_hz": -1}', "rate_hz"),
        (b'{"type": "subscribe", "rate_hz": "fast"}', "rate_hz"),
        (b'{"type": "unsubscribe"}', "type"),
        (b"not json", "bad subscribe message"),
    ],
)
async def test_a_bad_subscription_is_refused_with_why(
    hmi: Running, message: bytes, why: str
) -> None:
    async with connect(hmi.robot_ws_url("robot")) as connection:
        assert orjson.loads(await connection.recv())["type"] == "hello"
        await connection.send(message.decode())
        with pytest.raises(ConnectionClosed) as closed:
            await read_until_closed(connection)
    assert closed.value.rcvd is not None
    assert closed.value.rcvd.code == 4400
    assert why in closed.value.rcvd.reason
    # The service stays up for the next client.
    async with connect(hmi.robot_ws_url("robot")) as connection:
        assert orjson.loads(await connection.recv())["type"] == "hello"


async def test_permessage_deflate_is_negotiated(hmi: Running) -> None:
    async with connect(hmi.robot_ws_url("robot"), compression="deflate") as connection:
        assert orjson.loads(await connection.recv())["type"] == "hello"
        assert connection.response is not None
        extensions = connection.response.headers.get("Sec-WebSocket-Extensions", "")
        assert "permessage-deflate" in extensions
        assert any(type(e).__name__ == "PerMessageDeflate" for e in connection.protocol.extensions)


def test_the_kiosk_settings_are_checked_and_sorted() -> None:
    from pydantic import ValidationError

    from cobot_hmi.service.kiosk.kiosk_settings import KioskSettings

    settings = KioskSettings(shift_starts="22:00,06:00,14:00", kiosk_plot_window_s=45)  # type: ignore[arg-type]
    assert settings.kiosk_hello() == {
        "plot_window_s": 45.0,
        "shift_starts": ["06:00", "14:00", "22:00"],
    }
    for bad, why in (
        ("25:00", "HH:MM"),
        ("6:00", "HH:MM"),
        ("06:00,06:00", "twice"),
        ("", "at least one"),
    ):
        with pytest.raises(ValidationError, match=why):
            KioskSettings(shift_starts=bad)  # type: ignore[arg-type]
    with pytest.raises(ValidationError):
        KioskSettings(kiosk_plot_window_s=1)


async def test_the_hello_carries_the_kiosk_settings(hmi: Running) -> None:
    async with connect(hmi.robot_ws_url("robot")) as connection:
        hello = orjson.loads(await connection.recv())
    assert hello["kiosk"] == {"plot_window_s": 30.0, "shift_starts": ["06:00", "14:00", "22:00"]}


async def test_the_fan_out_encodes_once_per_group_not_per_client(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Five clients in two groups (every field; two fields at 50 Hz): every client of a group is
    handed the same text, and each distinct frame is turned into JSON once per group's fields."""
    from cobot_hmi.codec import zero_frame
    from cobot_hmi.service.robots import websocket_fanout as hub_module
    from cobot_hmi.service.robots.frame_notifier import FrameNotifier
    from cobot_hmi.service.robots.websocket_fanout import Subscription, WebSocketFanOut

    encoded: list[object] = []
    from cobot_hmi.codec import dumps as real_dumps

    def counting_dumps(data: object) -> bytes:
        if isinstance(data, dict) and "robot_state" in data:
            encoded.append(data)
        return real_dumps(data)

    monkeypatch.setattr(hub_module, "dumps", counting_dumps)
    hub = WebSocketFanOut(robot="r", batch_s=0.05, client_queue_frames=1000, stall_timeout_s=5)
    notifier = FrameNotifier("r", frames_per_wake=5)
    notifier.add(hub)
    texts: dict[int, list[str]] = {}

    def sink(n: int) -> Any:
        async def send(text: str) -> None:
            texts.setdefault(n, []).append(text)

        return send

    async def no_abort(_: str) -> None:
        return None

    clients = [hub.add_client(sink(n), no_abort, None, {"type": "hello"}) for n in range(5)]
    narrow = Subscription(("robot_state", "servo_on"), 50.0)
    for client in clients[2:]:
        hub.subscribe(client, narrow)
    frames = [zero_frame()._replace(robot_state=i) for i in range(10)]
    for i, frame in enumerate(frames):  # ten distinct frames, 10 ms apart
        notifier.publish(frame, b"", 1000.0 + i * 0.01, i)
        if i % 5 == 4:
            notifier.dispatch_now()
    for _ in range(50):
        await asyncio.sleep(0)
    await hub.close()
    wide = [t for t in texts[0] if '"frames"' in t]
    assert wide == [t for t in texts[1] if '"frames"' in t] and len(wide) == 2
    narrow_texts = [[t for t in texts[n] if '"frames"' in t] for n in (2, 3, 4)]
    assert narrow_texts[0] == narrow_texts[1] == narrow_texts[2]
    sent = [f for t in narrow_texts[0] for f in orjson.loads(t)["frames"]]
    assert 4 <= len(sent) <= 6  # 50 Hz of 100
    assert all(set(f["frame"]) == {"robot_state", "robot_state_name", "servo_on"} for f in sent)
    # Ten frames for the wide group, the decimated ones for the narrow: never once per client.
    assert len(encoded) == 10 + len(sent)

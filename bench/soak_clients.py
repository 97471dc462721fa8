"""``bench/soak``'s clients of the service: WebSocket readers, the writer, the MQTT watcher.

A ``StreamClient`` reads one robot's stream for the whole run, reconnecting when the service
closes it, and notes what it lost: the service's frame counter ``seq`` stepping by more than one
(frames this client never got) and, between consecutive frames, the wire's ``t2o_sequence``
stepping by more than one (packets the service never got). ``pause`` makes it stop reading (the
library then stops reading the socket once its queue is full: a frozen browser tab).

The ``Writer`` logs in as an operator, holds control of every robot and makes one write a second,
in turn to each robot: all sixteen ControlBox outputs set to the write's number (mod 2¹⁶), so each
write's image is its own and can be found again in the audit and in the recording.

The ``MqttWatcher`` subscribes to ``spBv1.0/#`` on the local broker and counts what arrives;
a ``BirthProbe`` waits for the edge node's birth after a broker restart.
"""

from __future__ import annotations

import asyncio
import contextlib
import re
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import httpx
import orjson
import paho.mqtt.client as mqtt
from paho.mqtt.enums import CallbackAPIVersion
from service_bench_support import BENCH_USER
from websockets.asyncio.client import ClientConnection, connect
from websockets.exceptions import ConnectionClosed, InvalidHandshake, InvalidStatus

from cobot_hmi.sparkplug.payload import parse_payload

WIRE_RESTART_STEP = 10_000
"""A ``t2o_sequence`` step larger than this (or zero or backwards) is a new connection's
numbering, not lost packets."""
EVENT_KINDS = ("recording", "alarm", "connection")
FRAMES_START = b'{"type":"frames"'
FRAME_NUMBERS = re.compile(rb'"seq":(\d+),"t":([-0-9.e+]+),"t2o_sequence":(\d+|null),"frame"')
"""Each frame's numbers in a ``frames`` message, as the service writes them
(``service.robots.websocket_fanout``)."""
OUTPUTS = 16


def wire_step_lost(step: int) -> int | None:
    """Packets lost between two consecutive frames' wire numbers ``step`` apart (mod 2³²);
    ``None`` for a new connection's numbering."""
    step &= 0xFFFFFFFF
    if step == 0 or step > WIRE_RESTART_STEP:
        return None
    return step - 1


@dataclass
class StreamClient:
    url: str
    robot: str
    index: int
    frames: int = 0
    last_seq: int | None = None
    last_wire: int | None = None
    newest_t: float = 0.0
    """The service's receive time of the newest frame read."""
    ws_losses: list[tuple[float, int]] = field(default_factory=list)
    """(the next frame's receive time, frames this client missed): ``seq`` gaps."""
    wire_losses: list[tuple[float, int | None]] = field(default_factory=list)
    """(the next frame's receive time, packets lost on the wire, None: a new connection)."""
    dropped_told: int = 0
    connects: list[float] = field(default_factory=list)
    """When each connection attempt began."""
    closes: list[tuple[float, str]] = field(default_factory=list)
    events: list[dict[str, Any]] = field(default_factory=list)
    monitor: bool = False
    """The bench's own instrument (``?rate=``, decimated by the service): it keeps the events
    and counts no losses."""
    reading: asyncio.Event = field(default_factory=asyncio.Event)
    _watches: list[tuple[float, bool, asyncio.Future[float]]] = field(default_factory=list)

    def pause(self) -> None:
        self.reading.clear()

    def resume(self) -> None:
        self.reading.set()

    async def first_frame_after(
        self, t: float, timeout_s: float, *, arrival: bool = False
    ) -> float | None:
        """The first frame this client reads that the service received after ``t``: its
        receive time, or (``arrival``) when it reached this client."""
        future: asyncio.Future[float] = asyncio.get_running_loop().create_future()
        self._watches.append((t, arrival, future))
        try:
            return await asyncio.wait_for(future, timeout_s)
        except TimeoutError:
            return None
        finally:
            self._watches = [w for w in self._watches if w[2] is not future]

    async def run(self, stop: asyncio.Event) -> None:
        self.reading.set()
        while not stop.is_set():
            self.connects.append(time.time())
            try:
                async with connect(
                    self.url, max_size=None, max_queue=16, open_timeout=10, proxy=None
                ) as ws:
                    await self._read(ws, stop)
            except ConnectionClosed as closed:
                self.closes.append((time.time(), f"{closed.rcvd or closed.sent}"))
            except (OSError, InvalidHandshake, InvalidStatus, TimeoutError) as error:
                self.closes.append((time.time(), f"connect: {error}"))
            if not stop.is_set():
                await asyncio.sleep(0.1)

    async def _read(self, ws: ClientConnection, stop: asyncio.Event) -> None:
        while not stop.is_set():
            await self.reading.wait()
            try:
                data = await asyncio.wait_for(ws.recv(decode=False), 1.0)
            except TimeoutError:
                continue
            if data.startswith(FRAMES_START):
                # Only the numbers the bench needs, without building every frame's objects
                # (several times cheaper: 20 clients read 6000 frames a second).
                found = FRAME_NUMBERS.findall(data)
                if found:
                    self._frames(
                        [(int(s), float(t), None if w == b"null" else int(w)) for s, t, w in found]
                    )
                    continue
            message = orjson.loads(data)
            kind = message["type"]
            if kind == "frames":
                self._frames([(f["seq"], f["t"], f["t2o_sequence"]) for f in message["frames"]])
            elif kind == "dropped":
                self.dropped_told += message["count"]
            elif kind == "event" and self.monitor:
                event = message["event"]
                if event["kind"] in EVENT_KINDS:
                    self.events.append(event)

    def _frames(self, frames: list[tuple[int, float, int | None]]) -> None:
        """Each frame's ``seq``, receive time and wire number, in order."""
        last_seq, last_wire = self.last_seq, self.last_wire
        for seq, t, wire in frames:
            if last_seq is not None and not self.monitor:
                step = seq - last_seq
                if step > 1:
                    self.ws_losses.append((t, step - 1))
                elif step == 1 and last_wire is not None and wire is not None:
                    lost = wire_step_lost(wire - last_wire)
                    if lost != 0:
                        self.wire_losses.append((t, lost))
            last_seq, last_wire = seq, wire
            if self._watches:
                for after, arrival, future in self._watches:
                    if t > after and not future.done():
                        future.set_result(time.time() if arrival else t)
        self.frames += len(frames)
        self.last_seq, self.last_wire = last_seq, last_wire
        if frames:
            self.newest_t = frames[-1][1]


# --------------------------------------------------------------------------- the writer


@dataclass
class WriteRecord:
    number: int
    robot: str
    pattern: int
    sent: float
    done: float
    status: int
    """The answer's HTTP status (0: no answer)."""
    reason: str = ""


def pattern_body(pattern: int) -> dict[str, dict[str, bool]]:
    return {"controlbox_do": {str(i): bool(pattern >> i & 1) for i in range(OUTPUTS)}}


@dataclass
class Writer:
    base_url: str
    robots: list[str]
    records: list[WriteRecord] = field(default_factory=list)
    control_takes: int = 0
    logins: int = 0

    async def _login(self, client: httpx.AsyncClient) -> None:
        answer = await client.post(
            "/api/v1/auth/login", json={"username": BENCH_USER[0], "password": BENCH_USER[1]}
        )
        answer.raise_for_status()
        # A script authenticates with its token (the cookie alone is for the HMI's own pages).
        client.headers["Authorization"] = f"Bearer {answer.json()['token']}"
        client.cookies.clear()
        self.logins += 1

    async def _take(self, client: httpx.AsyncClient, robot: str) -> None:
        answer = await client.post(f"/api/v1/robots/{robot}/control/take")
        if answer.status_code == 200:
            self.control_takes += 1

    async def run(self, stop: asyncio.Event) -> None:
        async with httpx.AsyncClient(base_url=self.base_url, timeout=10.0, trust_env=False) as c:
            await self._login(c)
            for robot in self.robots:
                await self._take(c, robot)
            started = time.monotonic()
            number = 0
            while not stop.is_set():
                number += 1
                robot = self.robots[number % len(self.robots)]
                await self._write(c, number, robot)
                # One a second, on the second; a write that took longer skips the ticks it ate.
                elapsed = time.monotonic() - started
                with contextlib.suppress(TimeoutError):
                    await asyncio.wait_for(stop.wait(), 1.0 - elapsed % 1.0)

    async def _write(self, client: httpx.AsyncClient, number: int, robot: str) -> None:
        pattern = number & 0xFFFF
        body = pattern_body(pattern)
        path = f"/api/v1/robots/{robot}/command"
        sent = time.time()
        status, reason = 0, ""
        for attempt in range(2):
            try:
                answer = await client.patch(path, json=body)
            except httpx.HTTPError as error:
                status, reason = 0, f"{type(error).__name__}: {error}"
                break
            status = answer.status_code
            reason = "" if status == 200 else _reason(answer)
            if attempt == 0 and status == 401:
                await self._login(client)  # the session ended: log in again, retry once
                await self._take(client, robot)
            elif attempt == 0 and status == 409 and "control" in reason:
                await self._take(client, robot)  # control went with the connection
            else:
                break
        self.records.append(WriteRecord(number, robot, pattern, sent, time.time(), status, reason))


def _reason(answer: httpx.Response) -> str:
    try:
        detail = answer.json().get("detail")
    except ValueError:
        return answer.text[:200]
    if isinstance(detail, dict):
        return str(detail.get("reason", detail))
    return str(detail)


# --------------------------------------------------------------------------- MQTT


@dataclass
class Subscriber:
    """A paho client of the local broker on its own network thread."""

    host: str
    port: int
    client: mqtt.Client | None = None

    def _open(self, topic: str, *, resubscribe: bool = False) -> None:
        """Connect, subscribe to ``topic`` (again after each reconnect: ``resubscribe``)."""
        client = mqtt.Client(CallbackAPIVersion.VERSION2, protocol=mqtt.MQTTv311)
        client.on_message = self._on_message
        if resubscribe:
            client.reconnect_delay_set(1, 2)
            client.on_connect = lambda c, *_: self._on_connect(c, topic)
        client.connect(self.host, self.port)
        if not resubscribe:
            client.subscribe(topic, qos=0)
        client.loop_start()
        self.client = client

    def _on_connect(self, client: mqtt.Client, topic: str) -> None:
        client.subscribe(topic, qos=0)

    def _on_message(
        self, _client: mqtt.Client, _userdata: object, message: mqtt.MQTTMessage
    ) -> None:
        raise NotImplementedError

    def stop(self) -> None:
        if self.client is not None:
            self.client.disconnect()
            self.client.loop_stop()
            self.client = None


@dataclass
class MqttWatcher(Subscriber):
    """``spBv1.0/#`` on the local broker: messages by type, births' times, historical DDATA;
    it subscribes again after each reconnect."""

    counts: dict[str, int] = field(default_factory=dict)
    node_births: list[float] = field(default_factory=list)
    historical: int = 0
    connects: int = 0
    lock: threading.Lock = field(default_factory=threading.Lock)

    def start(self) -> None:
        self._open("spBv1.0/#", resubscribe=True)

    def _on_connect(self, client: mqtt.Client, topic: str) -> None:
        with self.lock:
            self.connects += 1
        super()._on_connect(client, topic)

    def _on_message(
        self, _client: mqtt.Client, _userdata: object, message: mqtt.MQTTMessage
    ) -> None:
        parts = message.topic.split("/")
        kind = parts[2] if len(parts) > 2 else "?"
        historical = 0
        if kind == "DDATA":
            payload = parse_payload(bytes(message.payload))
            historical = int(any(m.is_historical for m in payload.metrics))
        with self.lock:
            self.counts[kind] = self.counts.get(kind, 0) + 1
            self.historical += historical
            if kind == "NBIRTH":
                self.node_births.append(time.time())


@dataclass
class BirthProbe(Subscriber):
    """A subscriber to NBIRTH alone, connected the moment a restarted broker accepts
    connections: it is in before the edge node's first reconnect attempt (paho waits at least
    a second), so the time its birth arrives is the service's recovery, to the millisecond."""

    born_at: float | None = None

    def start(self) -> None:
        self._open("spBv1.0/+/NBIRTH/+")

    def _on_message(
        self, _client: mqtt.Client, _userdata: object, message: mqtt.MQTTMessage
    ) -> None:
        if self.born_at is None:
            self.born_at = time.time()

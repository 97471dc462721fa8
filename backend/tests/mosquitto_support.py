"""A real Mosquitto broker for the Sparkplug tests, and a subscriber that reads Sparkplug B
payloads without the product's code.

The broker is Debian's ``mosquitto`` (``make test`` installs it) started with a generated config
on the test's own loopback address: ``listener PORT 127.x.y.z``, anonymous clients, no
persistence unless a test asks for it (the broker-restart test keeps the subscriber's session
across the restart, so nothing it should see can slip past it while it reconnects).

``decode_payload`` is a minimal protobuf wire-format reader written from the Sparkplug B
specification's field numbers (Payload: 1 timestamp, 2 metrics, 3 seq; Metric: 1 name, 2 alias,
3 timestamp, 4 datatype, 5 is_historical, 9 properties, 10–15 values), independent of the
product's generated classes: a mistake in the schema or in our encoder shows up as a mismatch.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import shutil
import signal
import socket
import struct
import threading
import time
from collections.abc import AsyncIterator, Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import paho.mqtt.client as mqtt
import pytest
from paho.mqtt.enums import CallbackAPIVersion

from conftest import free_tcp_port


def mosquitto_binary() -> str | None:
    found = shutil.which("mosquitto")
    if found:
        return found
    return "/usr/sbin/mosquitto" if os.access("/usr/sbin/mosquitto", os.X_OK) else None


needs_mosquitto = pytest.mark.skipif(
    mosquitto_binary() is None,
    reason="mosquitto is not installed (make test installs Debian's mosquitto)",
)


# --------------------------------------------------------------------------- wire format


def _varint(data: bytes, offset: int) -> tuple[int, int]:
    result = shift = 0
    while True:
        byte = data[offset]
        offset += 1
        result |= (byte & 0x7F) << shift
        if not byte & 0x80:
            return result, offset
        shift += 7


def _fields(data: bytes) -> list[tuple[int, int, Any]]:
    """``(field number, wire type, value)`` of one message: ints, bytes, or raw 4/8 bytes."""
    out = []
    offset = 0
    while offset < len(data):
        key, offset = _varint(data, offset)
        number, wire = key >> 3, key & 7
        value: int | bytes
        if wire == 0:
            value, offset = _varint(data, offset)
        elif wire == 2:
            length, offset = _varint(data, offset)
            value = data[offset : offset + length]
            offset += length
        elif wire == 5:
            value = data[offset : offset + 4]
            offset += 4
        elif wire == 1:
            value = data[offset : offset + 8]
            offset += 8
        else:
            raise ValueError(f"wire type {wire}")
        out.append((number, wire, value))
    return out


@dataclass
class Metric:
    name: str | None = None
    alias: int | None = None
    timestamp: int | None = None
    datatype: int | None = None
    is_historical: bool = False
    value: Any = None
    properties: dict[str, Any] = field(default_factory=dict)


@dataclass
class Message:
    topic: str
    timestamp: int | None
    seq: int | None
    metrics: list[Metric]
    received_at: float
    size: int

    @property
    def kind(self) -> str:
        return self.topic.split("/")[2]

    @property
    def device(self) -> str | None:
        parts = self.topic.split("/")
        return parts[4] if len(parts) > 4 else None


def _property_set(data: bytes) -> dict[str, Any]:
    keys: list[str] = []
    values: list[Any] = []
    for number, _, value in _fields(data):
        if number == 1:
            keys.append(value.decode())
        elif number == 2:
            decoded: Any = None
            for n, _, v in _fields(value):
                if n in (3, 4):
                    decoded = v
                elif n == 5:
                    decoded = struct.unpack("<f", v)[0]
                elif n == 6:
                    decoded = struct.unpack("<d", v)[0]
                elif n == 7:
                    decoded = bool(v)
                elif n == 8:
                    decoded = v.decode()
            values.append(decoded)
    return dict(zip(keys, values, strict=True))


def _metric(data: bytes) -> Metric:
    metric = Metric()
    for number, _, value in _fields(data):
        if number == 1:
            metric.name = value.decode()
        elif number == 2:
            metric.alias = value
        elif number == 3:
            metric.timestamp = value
        elif number == 4:
            metric.datatype = value
        elif number == 5:
            metric.is_historical = bool(value)
        elif number == 9:
            metric.properties = _property_set(value)
        elif number in (10, 11):
            metric.value = value
        elif number == 12:
            metric.value = struct.unpack("<f", value)[0]
        elif number == 13:
            metric.value = struct.unpack("<d", value)[0]
        elif number == 14:
            metric.value = bool(value)
        elif number == 15:
            metric.value = value.decode()
    return metric


def decode_payload(topic: str, data: bytes, received_at: float) -> Message:
    timestamp = seq = None
    metrics = []
    for number, _, value in _fields(data):
        if number == 1:
            timestamp = value
        elif number == 2:
            metrics.append(_metric(value))
        elif number == 3:
            seq = value
    return Message(topic, timestamp, seq, metrics, received_at, len(data))


def field_key(number: int, wire: int) -> bytes:
    """A protobuf field's key: its number and wire type, as a varint."""
    return encode_varint(number << 3 | wire)


def encode_varint(value: int) -> bytes:
    """A protobuf varint: seven bits a byte, the low ones first."""
    out = bytearray()
    while True:
        byte = value & 0x7F
        value >>= 7
        if value:
            out.append(byte | 0x80)
        else:
            out.append(byte)
            return bytes(out)


def encode_command(metrics: list[tuple[str | None, int | None, int, Any]]) -> bytes:
    """A command payload: ``(name, alias, datatype, value)`` per metric (bool, float or int)."""
    body = field_key(1, 0) + encode_varint(int(time.time() * 1000))
    for name, alias, datatype, value in metrics:
        metric = b""
        if name is not None:
            raw = name.encode()
            metric += field_key(1, 2) + encode_varint(len(raw)) + raw
        if alias is not None:
            metric += field_key(2, 0) + encode_varint(alias)
        metric += field_key(4, 0) + encode_varint(datatype)
        if isinstance(value, bool):
            metric += field_key(14, 0) + encode_varint(int(value))
        elif isinstance(value, float):
            metric += field_key(12, 5) + struct.pack("<f", value)
        else:
            metric += field_key(10, 0) + encode_varint(value)
        body += field_key(2, 2) + encode_varint(len(metric)) + metric
    return body


# --------------------------------------------------------------------------- the broker


@dataclass
class Broker:
    host: str
    port: int
    config: Path
    process: asyncio.subprocess.Process | None = None

    @property
    def url(self) -> str:
        return f"mqtt://{self.host}:{self.port}"

    async def start(self) -> None:
        binary = mosquitto_binary()
        assert binary is not None
        self.process = await asyncio.create_subprocess_exec(
            binary,
            "-c",
            str(self.config),
            stdout=asyncio.subprocess.DEVNULL,
            stderr=asyncio.subprocess.DEVNULL,
        )
        deadline = time.monotonic() + 20
        while True:
            assert self.process.returncode is None, "mosquitto exited"
            with (
                contextlib.suppress(OSError),
                socket.create_connection((self.host, self.port), timeout=1),
            ):
                return
            assert time.monotonic() < deadline, "mosquitto did not listen"
            await asyncio.sleep(0.05)

    async def stop(self, sig: int = signal.SIGTERM) -> None:
        process = self.process
        if process is None or process.returncode is not None:
            return
        process.send_signal(sig)
        try:
            async with asyncio.timeout(20):
                await process.wait()
        except TimeoutError:
            process.kill()
            await process.wait()


def broker_config(
    host: str,
    directory: Path,
    *,
    persistent: bool = False,
    port: int | None = None,
    lines: tuple[str, ...] = (),
) -> Broker:
    """A broker on ``host`` (a free port unless given), its config written, not started.
    ``lines`` replace the plain anonymous listener (their own listeners and security)."""
    port = port if port is not None else free_tcp_port(host)
    config = directory / "mosquitto.conf"
    body = list(lines) or [f"listener {port} {host}", "allow_anonymous true"]
    body += [f"persistence {'true' if persistent else 'false'}", "log_dest none"]
    if os.geteuid() == 0:
        # As root Mosquitto drops to the user "mosquitto", who cannot read a test's private
        # temporary directory (certificates, password file, persistence): stay who we are.
        body.append("user root")
    if persistent:
        body += [f"persistence_location {directory}/", "queue_qos0_messages true"]
    config.write_text("\n".join(body) + "\n")
    return Broker(host, port, config)


@contextlib.asynccontextmanager
async def mosquitto(
    host: str,
    directory: Path,
    *,
    persistent: bool = False,
    port: int | None = None,
    lines: tuple[str, ...] = (),
    start: bool = True,
) -> AsyncIterator[Broker]:
    """Mosquitto on ``host``, stopped at the end whatever happens (``start=False``: the test
    starts it when it wants)."""
    broker = broker_config(host, directory, persistent=persistent, port=port, lines=lines)
    if start:
        await broker.start()
    try:
        yield broker
    finally:
        await broker.stop()


# --------------------------------------------------------------------------- a subscriber


class Subscriber:
    """Every message under ``spBv1.0/#`` decoded with ``decode_payload``, in arrival order."""

    def __init__(self, broker: Broker, *, client_id: str = "", persistent: bool = False) -> None:
        self.broker = broker
        self.messages: list[Message] = []
        self._lock = threading.Lock()
        self._subscribed = threading.Event()
        self.client = mqtt.Client(
            CallbackAPIVersion.VERSION2,
            client_id=client_id,
            clean_session=not persistent,
            protocol=mqtt.MQTTv311,
        )
        self.client.reconnect_delay_set(1, 1)
        self.client.on_connect = self._on_connect
        self.client.on_message = self._on_message
        self.client.on_subscribe = self._on_subscribe

    def _on_connect(self, client: mqtt.Client, *_: Any) -> None:
        client.subscribe("spBv1.0/#", qos=1)

    def _on_subscribe(self, *_: Any) -> None:
        self._subscribed.set()

    def _on_message(self, _client: mqtt.Client, _userdata: Any, message: Any) -> None:
        received_at = time.time()
        try:
            decoded = decode_payload(message.topic, bytes(message.payload), received_at)
        except (IndexError, ValueError, UnicodeDecodeError, struct.error):
            # Not a payload (a test's own garbage command): kept, without metrics.
            decoded = Message(message.topic, None, None, [], received_at, len(message.payload))
        with self._lock:
            self.messages.append(decoded)

    async def __aenter__(self) -> Subscriber:
        self.client.connect(self.broker.host, self.broker.port, keepalive=30)
        self.client.loop_start()
        assert await asyncio.to_thread(self._subscribed.wait, 20), "no SUBACK"
        return self

    async def __aexit__(self, *_: object) -> None:
        self.client.disconnect()
        await asyncio.to_thread(self.client.loop_stop)

    def publish(self, topic: str, payload: bytes, *, retain: bool = False) -> None:
        self.client.publish(topic, payload, qos=1, retain=retain)

    def snapshot(self) -> list[Message]:
        with self._lock:
            return list(self.messages)

    def of(self, kind: str, device: str | None = None) -> list[Message]:
        return [
            m for m in self.snapshot() if m.kind == kind and (device is None or m.device == device)
        ]

    async def wait_for(
        self, check: Callable[[list[Message]], object], timeout_s: float = 30.0
    ) -> None:
        """Until ``check(messages)`` is truthy (a generous functional deadline)."""
        deadline = time.monotonic() + timeout_s
        while not check(self.snapshot()):
            assert time.monotonic() < deadline, "the broker did not show it in time"
            await asyncio.sleep(0.05)


def kill(process: asyncio.subprocess.Process) -> None:
    process.send_signal(signal.SIGKILL)

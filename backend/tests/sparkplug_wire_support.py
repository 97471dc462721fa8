"""Reading the edge node from outside, twice over: a subscriber that decodes every payload with
the official Eclipse Tahu schema (``sparkplug/sparkplug_b.proto`` compiled here by protoc into a
descriptor pool of its own, so the product's generated classes play no part), and a tshark
capture of the broker's port on loopback (Wireshark's MQTT dissector: what went over the wire,
when, from which client).

tshark is installed by ``make test`` (Makefile ``system-deps``); a missing tshark fails the
tests that use it, never skips them.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import re
import shutil
import signal
import tempfile
import threading
import time
import uuid
from collections import Counter
from collections.abc import AsyncIterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import orjson
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

from mosquitto_support import Broker, Subscriber

PROTO = Path(__file__).resolve().parents[1] / "src/cobot_hmi/sparkplug/sparkplug_b.proto"


@functools.cache
def tahu_payload() -> Any:
    """The ``org.eclipse.tahu.protobuf.Payload`` class, from the .proto file by protoc."""
    from grpc_tools import protoc  # type: ignore[import-untyped]

    with tempfile.TemporaryDirectory(prefix="tahu-") as out:
        descriptors = Path(out) / "sparkplug_b.pb"
        status = protoc.main(
            [
                "protoc",
                f"--proto_path={PROTO.parent}",
                f"--descriptor_set_out={descriptors}",
                PROTO.name,
            ]
        )
        assert status == 0, f"protoc failed on {PROTO}"
        files = descriptor_pb2.FileDescriptorSet.FromString(descriptors.read_bytes())
    pool = descriptor_pool.DescriptorPool()
    for file in files.file:
        pool.Add(file)
    return message_factory.GetMessageClass(
        pool.FindMessageTypeByName("org.eclipse.tahu.protobuf.Payload")
    )


def decode(data: bytes) -> Any:
    """A Sparkplug B payload decoded with the Tahu schema."""
    return tahu_payload().FromString(data)


@dataclass(frozen=True)
class Heard:
    """A message as a subscriber (or the capture) saw it, its payload decoded with Tahu."""

    topic: str
    payload: Any
    at_s: float

    @property
    def kind(self) -> str:
        return self.topic.split("/")[2]

    @property
    def device(self) -> str | None:
        parts = self.topic.split("/")
        return parts[4] if len(parts) > 4 else None

    @property
    def historical(self) -> bool:
        return any(m.is_historical for m in self.payload.metrics)

    def content(self) -> tuple[tuple[int, int, str], ...]:
        """What the message says (each metric's alias, capture time and value), without the
        envelope (seq, payload timestamp) that a second sending of it would change."""
        return tuple(
            (m.alias, m.timestamp, str(getattr(m, m.WhichOneof("value") or "is_null")))
            for m in self.payload.metrics
        )


class TahuSubscriber(Subscriber):
    """``Subscriber`` that also keeps each message decoded with the Tahu schema."""

    def __init__(self, broker: Broker, *, client_id: str, persistent: bool = False) -> None:
        super().__init__(broker, client_id=client_id, persistent=persistent)
        self.heard: list[Heard] = []
        self._heard_lock = threading.Lock()

    def _on_message(self, client: Any, userdata: Any, message: Any) -> None:
        super()._on_message(client, userdata, message)
        heard = Heard(str(message.topic), decode(bytes(message.payload)), time.time())
        with self._heard_lock:
            self.heard.append(heard)

    async def __aenter__(self) -> TahuSubscriber:
        await super().__aenter__()
        return self

    def heard_so_far(self) -> list[Heard]:
        with self._heard_lock:
            return list(self.heard)


# --------------------------------------------------------------------------- the capture


@dataclass
class Capture:
    path: Path
    broker_port: int
    dropped: int | None = None
    """Packets the capture itself says it dropped (its kernel buffer full on a busy machine),
    known once it has stopped."""

    async def catch_up(self, peer: Subscriber, timeout_s: float = 60.0) -> None:
        """Until every packet sent so far is in the file: a marker published now is (dumpcap
        reads the interface in order; stopping it drops what it has not read yet)."""
        topic = f"capture/marker/{uuid.uuid4().hex}"
        peer.client.publish(topic, b"", qos=0)
        deadline = time.monotonic() + timeout_s
        while True:
            process = await asyncio.create_subprocess_exec(
                "tshark",
                "-r",
                str(self.path),
                "-d",
                f"tcp.port=={self.broker_port},mqtt",
                "-Y",
                f'mqtt.topic == "{topic}"',
                stdout=asyncio.subprocess.PIPE,
                stderr=asyncio.subprocess.DEVNULL,
            )
            out, _ = await process.communicate()  # a packet cut short at the end: said, not fatal
            if out.strip():
                return
            assert time.monotonic() < deadline, "the capture did not catch up"
            await asyncio.sleep(0.2)


@contextlib.asynccontextmanager
async def capture(host: str, port: int, path: Path) -> AsyncIterator[Capture]:
    """tshark writing every packet to or from ``host:port`` (the broker) on loopback into
    ``path``; ``catch_up`` before the end, or the last packets may be missing."""
    assert shutil.which("tshark"), "tshark missing: `make test` installs it"
    tshark = await asyncio.create_subprocess_exec(
        "tshark",
        "-i",
        "lo",
        "-w",
        str(path),
        "-B",
        "64",  # MiB of kernel buffer (2 by default): a replay's burst on a busy machine fits
        "-f",
        f"host {host} and tcp port {port}",
        stdout=asyncio.subprocess.DEVNULL,
        stderr=asyncio.subprocess.PIPE,
    )
    record = Capture(path, port)
    try:
        assert tshark.stderr is not None
        started = b""
        while b"Capturing on" not in started:
            line = await asyncio.wait_for(tshark.stderr.readline(), 30)
            assert line, "tshark ended before capturing"
            started += line
        yield record
    finally:
        if tshark.returncode is None:
            tshark.send_signal(signal.SIGINT)
        _, said = await asyncio.wait_for(tshark.communicate(), 30)
        record.dropped = sum(int(n) for n in re.findall(rb"(\d+) packets? dropped", said))


@dataclass(frozen=True)
class Packet:
    """One MQTT control packet on the wire (a TCP segment may carry several)."""

    at_s: float
    to_broker: bool
    client_port: int
    message_type: int
    """MQTT's: 1 CONNECT, 2 CONNACK, 3 PUBLISH, 8 SUBSCRIBE, 12 PINGREQ, 14 DISCONNECT."""
    topic: str
    payload: bytes
    client_id: str


@dataclass(frozen=True)
class Wire:
    """The capture, read by tshark."""

    packets: list[Packet]
    accepts_s: list[float]
    """When the broker answered a TCP SYN (SYN-ACK), in order: it was listening then."""
    segments_missing: dict[int, int]
    """Per client port, the segments tshark found missing before one it holds (its TCP
    analysis: "previous segment not captured"): that connection's record is incomplete."""

    def publishes(self, client_port: int) -> list[Heard]:
        """One connection's PUBLISHes to the broker, their payloads decoded with Tahu."""
        return [
            Heard(p.topic, decode(p.payload), p.at_s)
            for p in self.packets
            if p.to_broker and p.client_port == client_port and p.message_type == 3
        ]

    def connects(self, client_id: str) -> list[Packet]:
        return [p for p in self.packets if p.message_type == 1 and p.client_id == client_id]


def _first(layer: dict[str, Any], name: str, default: str = "") -> str:
    value = layer.get(name, default)
    return str(value[0] if isinstance(value, list) else value)


async def read_capture(path: Path, broker_port: int) -> Wire:
    """Every MQTT packet of the capture, and the broker's SYN-ACKs."""
    process = await asyncio.create_subprocess_exec(
        "tshark",
        "-r",
        str(path),
        "-d",
        f"tcp.port=={broker_port},mqtt",
        "-Y",
        f"mqtt || tcp.analysis.lost_segment || "
        f"(tcp.flags.syn == 1 && tcp.flags.ack == 1 && tcp.srcport == {broker_port})",
        "-T",
        "json",
        "--no-duplicate-keys",  # several MQTT packets in one segment: a list, not lost keys
        "-J",
        "frame tcp mqtt",
        stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.PIPE,
    )
    out, err = await asyncio.wait_for(process.communicate(), 120)
    assert process.returncode == 0, err.decode()
    packets: list[Packet] = []
    accepts: list[float] = []
    missing: Counter[int] = Counter()
    for frame in orjson.loads(out or b"[]"):
        layers = frame["_source"]["layers"]
        at_s = float(_first(layers["frame"], "frame.time_epoch"))
        tcp = layers["tcp"]
        source, destination = int(_first(tcp, "tcp.srcport")), int(_first(tcp, "tcp.dstport"))
        client_port = source if destination == broker_port else destination
        if b"tcp.analysis.lost_segment" in orjson.dumps(tcp):
            missing[client_port] += 1
        if "mqtt" not in layers:
            flags = tcp.get("tcp.flags_tree", {})
            if source == broker_port and _first(flags, "tcp.flags.syn") in ("1", "True"):
                accepts.append(at_s)
            continue
        mqtt_layers = layers["mqtt"]
        for mqtt in mqtt_layers if isinstance(mqtt_layers, list) else [mqtt_layers]:
            message_type = int(_first(mqtt["mqtt.hdrflags_tree"], "mqtt.msgtype"))
            payload = _first(mqtt, "mqtt.msg").replace(":", "")
            packets.append(
                Packet(
                    at_s,
                    destination == broker_port,
                    client_port,
                    message_type,
                    _first(mqtt, "mqtt.topic"),
                    bytes.fromhex(payload),
                    _first(mqtt, "mqtt.clientid"),
                )
            )
    return Wire(packets, accepts, dict(missing))

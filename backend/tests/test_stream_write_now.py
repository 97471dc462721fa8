"""Frames messages written at once (``StreamClient.offer_frames``, ``ws_deflate.write_text_now``),
against the emulator over real sockets: a client that keeps up is written its frames without its
sender task, after its hello and in order; while its connection does not take writes (the
transport paused by flow control, as for a peer that stopped reading) the frames queue behind
the sender, and when it takes writes again they come in order, none lost, before the ones
written at once again. The robot is conftest's standing one: only the frames' order and
framing matter here. The client reads raw frames with websockets' sans-I/O parser (no
client-side checks of the server beyond the framing), so what it sees is what was written."""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from typing import Any

import orjson
import pytest
from websockets.client import ClientProtocol
from websockets.frames import Frame, Opcode
from websockets.uri import parse_uri

from cobot_hmi.service.api.ws_deflate import StreamWebSocketProtocol
from cobot_hmi.service.robots.websocket_fanout import StreamClient
from service_support import Running, hmi_fixture

pytestmark = pytest.mark.timeout(120)

DEADLINE_S = 60.0


hmi = hmi_fixture()


class RawStream:
    """A stream client on a plain socket: the handshake and frame parsing by websockets'
    sans-I/O client (no compression offered), every text frame kept as it came."""

    def __init__(
        self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter, protocol: ClientProtocol
    ) -> None:
        self.reader, self.writer, self.protocol = reader, writer, protocol
        self.frames: list[Frame] = []

    @classmethod
    async def open(cls, url: str) -> RawStream:
        uri = parse_uri(url)
        reader, writer = await asyncio.open_connection(uri.host, uri.port)
        stream = cls(reader, writer, ClientProtocol(uri))
        stream.protocol.send_request(stream.protocol.connect())
        await stream._flush()
        return stream

    async def _flush(self) -> None:
        for data in self.protocol.data_to_send():
            if data:
                self.writer.write(data)
        await self.writer.drain()

    async def read_until(self, done: Callable[[], bool]) -> None:
        async with asyncio.timeout(DEADLINE_S):
            while not done():
                data = await self.reader.read(65536)
                assert data, "the server closed the stream"
                self.protocol.receive_data(data)
                for event in self.protocol.events_received():
                    if isinstance(event, Frame) and event.opcode is Opcode.TEXT:
                        self.frames.append(event)
                await self._flush()

    def messages(self) -> list[dict[str, Any]]:
        return [orjson.loads(frame.data) for frame in self.frames]

    def seqs(self) -> list[int]:
        return [f["seq"] for m in self.messages() if m["type"] == "frames" for f in m["frames"]]

    async def close(self) -> None:
        self.writer.close()
        await self.writer.wait_closed()


async def stream_client(hmi: Running) -> StreamClient:
    hub = hmi.service.robot("robot").hub
    async with asyncio.timeout(DEADLINE_S):
        while not hub.clients:  # noqa: ASYNC110 - polls the hub the route adds it to
            await asyncio.sleep(0.01)
    (client,) = hub.clients
    return client


async def test_frames_are_written_at_once_after_the_hello_in_order(hmi: Running) -> None:
    stream = await RawStream.open(hmi.robot_ws_url("robot"))
    try:
        client = await stream_client(hmi)
        await stream.read_until(lambda: len(stream.seqs()) >= 50 and client.written_at_once >= 5)
    finally:
        await stream.close()
    messages = stream.messages()
    assert messages[0]["type"] == "hello"
    seqs = stream.seqs()
    assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))  # every frame, in order
    # As a server writes them (RFC 6455 §5.1, RFC 7692: no RSV1 without the extension).
    assert all(f.fin and not f.rsv1 for f in stream.frames)
    assert client.written_at_once <= client.messages_sent


async def test_frames_queue_while_the_connection_does_not_take_writes(hmi: Running) -> None:
    stream = await RawStream.open(hmi.robot_ws_url("robot"))
    try:
        client = await stream_client(hmi)
        await stream.read_until(lambda: client.written_at_once >= 3)
        assert client.write_now is not None
        protocol = client.write_now.__self__  # type: ignore[attr-defined]
        assert isinstance(protocol, StreamWebSocketProtocol)
        protocol.pause_writing()  # as the transport does over its high-water mark
        paused_at = client.written_at_once
        async with asyncio.timeout(DEADLINE_S):
            while not (client.queued_frames >= 20 and client.sending_since is not None):  # noqa: ASYNC110
                await asyncio.sleep(0.01)
        assert client.written_at_once == paused_at  # nothing written past the pause
        queued_seqs_from = len(stream.seqs())
        protocol.resume_writing()
        await stream.read_until(lambda: client.written_at_once >= paused_at + 3)
        await stream.read_until(lambda: len(stream.seqs()) >= queued_seqs_from + 40)
    finally:
        await stream.close()
    seqs = stream.seqs()
    assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))  # none lost, none reordered
    assert client.dropped_total == 0

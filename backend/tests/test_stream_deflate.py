"""permessage-deflate on ``WS /api/v1/robots/{name}/stream``, message by message
(``service.api.ws_deflate``), against the emulator over real sockets: a client of every field
is sent its frames uncompressed (RSV1 unset) on a connection that negotiated permessage-deflate,
every other message compressed; after a subscription to some fields its frames are compressed
too. The client is the ``websockets`` library's: each message it reads went through its own
permessage-deflate decoder, so a compressed message after uncompressed ones decodes only if the
service's compressor left them out of its window as the decoder does (RFC 7692)."""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator
from typing import Any

import orjson
import pytest
from websockets.asyncio.client import connect
from websockets.extensions.permessage_deflate import PerMessageDeflate
from websockets.frames import Frame, Opcode

from cobot_hmi.emulator.target import Target
from cobot_hmi.service.api.models import STREAM_MESSAGE
from service_support import Running, emulator, hmi_fixture

pytestmark = pytest.mark.timeout(120)


@pytest.fixture
async def target(robot_host: str) -> AsyncIterator[Target]:
    async with emulator(robot_host) as target:
        yield target


hmi = hmi_fixture(status_interval_s=0.2)


def watch_compression(deflate: PerMessageDeflate, seen: list[tuple[bool, str]]) -> None:
    """Note each text message the client's decoder is handed: compressed (RSV1) or not, and its
    type once decoded."""
    decode = deflate.decode

    def noted(frame: Frame, *, max_size: int | None = None) -> Frame:
        decoded = decode(frame, max_size=max_size)
        if frame.opcode is Opcode.TEXT:
            seen.append((frame.rsv1, orjson.loads(decoded.data)["type"]))
        return decoded

    deflate.decode = noted  # type: ignore[method-assign]


async def test_frames_of_every_field_go_uncompressed(hmi: Running) -> None:
    seen: list[tuple[bool, str]] = []
    messages: list[Any] = []
    async with connect(hmi.robot_ws_url("robot"), compression="deflate") as connection:
        deflates = [e for e in connection.protocol.extensions if isinstance(e, PerMessageDeflate)]
        assert deflates, "permessage-deflate was not negotiated"
        watch_compression(deflates[0], seen)

        async def read_until(done: Any) -> None:
            while not done():
                messages.append(orjson.loads(await connection.recv()))

        def kinds(compressed: bool) -> set[str]:
            return {kind for rsv1, kind in seen if rsv1 is compressed}

        # Every field: frames uncompressed, the status messages between them compressed.
        await asyncio.wait_for(
            read_until(lambda: "frames" in kinds(False) and "status" in kinds(True)), 60
        )
        assert "frames" not in kinds(True)
        subscribe = {"type": "subscribe", "fields": ["robot_state", "servo_on"], "rate_hz": 10}
        await connection.send(orjson.dumps(subscribe).decode())

        def after_subscribed() -> list[tuple[bool, str]]:
            kinds_seen = [kind for _, kind in seen]
            return seen[kinds_seen.index("subscribed") :] if "subscribed" in kinds_seen else []

        # Some fields: the frames compressed, and a status after them still decodes.
        await asyncio.wait_for(
            read_until(lambda: {(True, "frames"), (True, "status")} <= set(after_subscribed())),
            60,
        )
        assert all(rsv1 for rsv1, kind in after_subscribed() if kind == "frames")
    for message in messages:  # every one decoded to what the contract says
        STREAM_MESSAGE.validate_python(message)
    frames = [f for m in messages if m["type"] == "frames" for f in m["frames"]]
    assert frames and all("frame" in f for f in frames)

"""Layer: service. permessage-deflate (RFC 7692) on the streams, chosen message by message.

uvicorn's WebSocket protocol (websockets' sans-I/O implementation) compresses every message of a
connection that negotiated permessage-deflate, each with the connection's own compressor. For a
stream of every field at the robot's rate (a panel on the plant's network: ~2.5 kB of JSON a
frame, 100 frames/s at RPI 10 ms) that is a deflate per client per frame, which bench/fanout
measured at about 20 µs of the service's CPU per robot-frame per client: more than the rest of
the fan-out. A phone's subscription (a few fields at 10 frames/s) is cheap to compress and is
what the compression is for. So the connection negotiates permessage-deflate as before
(``StreamWebSocketProtocol``, the same offer uvicorn makes), and the stream may send one message
as it is (``send_plain``, RSV1 unset): RFC 7692 §6 lets an endpoint send a message uncompressed
on such a connection, and neither side's LZ77 window takes it in (§7.2.1: the compressor
continues from the last compressed message), so the connection's compressor skips it and the
messages after it still decompress.

Such a message need not wait for the stream's sender task either: ``write_text_now`` hands it to
the transport at once, framed once for every connection it goes to (``text_frame``), when the
connection is open and its transport takes writes (not paused by flow control). That is what
uvicorn's ``send`` does for it, less a task wake, three awaits and a framing per client, which
bench/fanout measured at most of the fan-out's CPU per message; where it cannot, the sender
sends it the usual way (``send_plain``) and a stalled peer is found as before.

Imports uvicorn and websockets only.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Sequence
from typing import Any, Final

from uvicorn.config import Config
from uvicorn.protocols.websockets.websockets_sansio_impl import WebSocketsSansIOProtocol
from uvicorn.server import ServerState
from websockets.extensions.base import Extension
from websockets.extensions.permessage_deflate import (
    PerMessageDeflate,
    ServerPerMessageDeflateFactory,
)
from websockets.frames import Frame, Opcode
from websockets.protocol import State
from websockets.server import ServerProtocol
from websockets.typing import ExtensionParameter

WINDOW_BITS: Final = 12
"""uvicorn's offer (4 KiB windows both ways), kept as it was."""
COMPRESS_SETTINGS: Final = {"memLevel": 5}


class _TextFrames:
    """The framing of the last message framed, kept by the message's identity."""

    message: bytes = b""
    framed: bytes = b""


def text_frame(message: bytes) -> bytes:
    """``message`` (UTF-8 text) as one final, unmasked, uncompressed text frame (RFC 6455 §5.2,
    a server's), framed by websockets. A broadcast writes the same bytes object to each client
    of its group in a row, so the last message's framing is kept by identity (no hash of the
    message): framed and copied once per broadcast. Called on the web loop only."""
    if message is not _TextFrames.message:
        _TextFrames.framed = Frame(Opcode.TEXT, message).serialize(mask=False)
        _TextFrames.message = message
    return _TextFrames.framed


class SelectiveDeflate(PerMessageDeflate):
    """permessage-deflate whose next message may go uncompressed (``plain_next``)."""

    plain_next = False

    def encode(self, frame: Frame) -> Frame:
        if self.plain_next:
            return frame  # RSV1 unset, the compressor not fed: its window stays as it was
        return super().encode(frame)


class SelectiveDeflateFactory(ServerPerMessageDeflateFactory):
    """The same negotiation as websockets' server factory, the extension a ``SelectiveDeflate``."""

    def process_request_params(
        self, params: Sequence[ExtensionParameter], accepted_extensions: Sequence[Extension]
    ) -> tuple[list[ExtensionParameter], PerMessageDeflate]:
        response, agreed = super().process_request_params(params, accepted_extensions)
        return response, SelectiveDeflate(
            agreed.remote_no_context_takeover,
            agreed.local_no_context_takeover,
            agreed.remote_max_window_bits,
            agreed.local_max_window_bits,
            agreed.compress_settings,
        )


class StreamWebSocketProtocol(WebSocketsSansIOProtocol):
    """uvicorn's WebSocket protocol with ``send_plain`` (uvicorn's ``ws`` option)."""

    def __init__(
        self,
        config: Config,
        server_state: ServerState,
        app_state: dict[str, Any],
        _loop: asyncio.AbstractEventLoop | None = None,
    ) -> None:
        super().__init__(config, server_state, app_state, _loop)
        if config.ws_per_message_deflate:  # as uvicorn builds it, with the selective extension
            factory = SelectiveDeflateFactory(
                server_max_window_bits=WINDOW_BITS,
                client_max_window_bits=WINDOW_BITS,
                compress_settings=dict(COMPRESS_SETTINGS),
            )
            self.conn = ServerProtocol(
                extensions=[factory],
                max_size=config.ws_max_size,
                logger=logging.getLogger("uvicorn.error"),
            )

    async def send_plain(self, text: str) -> None:
        """Send ``text`` as a text message, uncompressed even where permessage-deflate was
        negotiated. The stream's one sender calls it (a close or a ping meanwhile is a control
        frame, which is never compressed)."""
        deflate = next((e for e in self.conn.extensions if isinstance(e, SelectiveDeflate)), None)
        if deflate is None:
            await self.send({"type": "websocket.send", "text": text})
            return
        deflate.plain_next = True
        try:
            await self.send({"type": "websocket.send", "text": text})
        finally:
            deflate.plain_next = False

    def write_text_now(self, message: bytes) -> bool:
        """Write ``message`` (UTF-8 text) as one uncompressed text message now; False, and
        nothing written, unless the connection is open and its transport takes writes. The
        caller sends it the usual way then, after whatever it queued before it: a message is
        written now only when nothing of its stream waits (its sender is idle)."""
        if (
            self.close_sent
            or self.disconnected
            or not self.handshake_complete
            or self.initial_response is not None
            or not self.writable.is_set()
            or self.conn.state is not State.OPEN
            or self.transport.is_closing()
        ):
            return False
        # uvicorn writes out what the protocol has to send at every event and send, so nothing
        # of this connection waits in ``self.conn`` to go before this frame.
        self.transport.write(text_frame(message))
        return True

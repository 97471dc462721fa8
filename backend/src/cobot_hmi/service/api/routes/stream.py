"""Layer: service. ``WS /api/v1/robots/{name}/stream``: hello, batched frames at the asked rate,
status, events (``service.api.models.StreamMessage``); ``WS /api/v1/stream`` (deprecated) is the
first robot's.

The handshake may carry the session (cookie, bearer header, or ``?token=``); control of the
robot held by that session ends when its last stream to that robot closes. A refusal after the
handshake is a close with an application code: 4400 (bad ``rate``), 4401 (login required) or
4404 (unknown robot, the known ones named), the reason in the close.

A client may send ``subscribe`` messages (``service.api.models.SubscribeMessage``): the frame fields
it shows and the rate it draws at; the frames after the service's ``subscribed`` answer carry only
those fields at that rate (``robots.websocket_fanout``). A bad one is a close with 4400 and the
reason. When the session ends while the stream is open (logout, expiry, its user removed or given
another role, its API token revoked), the stream is closed at once with 1008 (policy violation, RFC
6455 §7.4.1) and the reason: it must not go on showing what the session may no longer see."""

from __future__ import annotations

import asyncio
import contextlib
import math
import socket
from collections.abc import Callable
from typing import Any, Final

from fastapi import APIRouter, WebSocket
from pydantic import ValidationError
from starlette.types import ASGIApp, Receive, Scope, Send

from cobot_hmi.layout import T2O_FIELDS
from cobot_hmi.service.api.deps import client_address, get_service, session_token
from cobot_hmi.service.api.models.stream import SUBSCRIBE_MESSAGE
from cobot_hmi.service.errors import UnknownRobotError
from cobot_hmi.service.robots.websocket_fanout import StreamClient, Subscription, WebSocketFanOut

router = APIRouter()

ABORT_KEY: Final = "cobot_hmi.abort_transport"
SEND_PLAIN_KEY: Final = "cobot_hmi.send_plain"
"""The server's ``send_plain`` (``ws_deflate``): a text message sent uncompressed."""
WRITE_TEXT_NOW_KEY: Final = "cobot_hmi.write_text_now"
"""The server's ``write_text_now`` (``ws_deflate``): an uncompressed text message written at
once if the connection takes it."""
CLOSE_BAD_REQUEST: Final = 4400
CLOSE_LOGIN_REQUIRED: Final = 4401
CLOSE_UNKNOWN_ROBOT: Final = 4404
CLOSE_STALLED: Final = 4408
CLOSE_SESSION_ENDED: Final = 1008
"""Policy violation (RFC 6455 §7.4.1): the stream's session ended."""
CLOSE_REASON_BYTES: Final = 123
"""A close frame's reason fits a control frame's 125 bytes after the 2-byte code."""
SEND_BUFFER_BYTES: Final = 128 * 1024
"""Kernel send buffer per stream connection (Linux doubles it): ~1 s of frames at 10 ms."""


class TransportAbortMiddleware:
    """Puts the server transport's ``abort`` in the WebSocket scope (uvicorn), and the
    server's ``send_plain`` and ``write_text_now`` where it has them
    (``ws_deflate.StreamWebSocketProtocol``).

    A client that stopped reading cannot be sent a close frame (it would wait behind the full
    send buffer forever) and ``transport.close()`` waits for that buffer to drain: only an
    abort (RST) frees the connection. ASGI has no abort, so this reaches for uvicorn's
    protocol object, which is the ``send`` callable's owner; elsewhere it adds nothing and
    a stalled client is sent a close instead (and every message goes as the server sends it).
    """

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "websocket":
            protocol = getattr(send, "__self__", None)
            transport = getattr(protocol, "transport", None)
            abort = getattr(transport, "abort", None)
            if callable(abort):
                scope = {**scope, ABORT_KEY: abort}
            send_plain = getattr(protocol, "send_plain", None)
            if callable(send_plain):
                scope = {**scope, SEND_PLAIN_KEY: send_plain}
            write_text_now = getattr(protocol, "write_text_now", None)
            if callable(write_text_now):
                scope = {**scope, WRITE_TEXT_NOW_KEY: write_text_now}
            _limit_send_buffer(transport)
        await self.app(scope, receive, send)


def _limit_send_buffer(transport: object) -> None:
    """Cap the kernel's send buffer of a stream connection.

    Linux grows a socket's send buffer up to megabytes: for a client that reads slowly that is
    many seconds of frames, old before they are read, and the bounded per-client queue (which
    drops the oldest frames and says so) would never come into play. Capped, a slow client is
    at most about a second behind and then loses old frames instead.
    """
    get_extra_info = getattr(transport, "get_extra_info", None)
    sock = get_extra_info("socket") if callable(get_extra_info) else None
    if sock is not None:
        with contextlib.suppress(OSError):
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, SEND_BUFFER_BYTES)


def close_reason(text: str) -> str:
    """``text`` cut to what a close frame carries (UTF-8 bytes, never half a character)."""
    return text.encode()[:CLOSE_REASON_BYTES].decode(errors="ignore")


FIELD_ORDER: Final = {f.name: i for i, f in enumerate(T2O_FIELDS)}


class BadSubscriptionError(ValueError):
    """A ``subscribe`` message that is no subscription: the client is told why in the close."""


def parse_subscription(text: str | bytes) -> Subscription:
    """A client's ``subscribe`` message as the hub's ``Subscription`` (its fields in the
    layout's order, so two clients asking the same fields in another order share a group)."""
    try:
        message = SUBSCRIBE_MESSAGE.validate_json(text)
    except ValidationError as error:
        first = error.errors()[0]
        where = ".".join(str(p) for p in first["loc"])
        raise BadSubscriptionError(f"bad subscribe message: {where}: {first['msg']}") from None
    if message.fields is None:
        return Subscription(None, message.rate_hz)
    unknown = sorted(set(message.fields) - FIELD_ORDER.keys())
    if unknown:
        raise BadSubscriptionError(f"bad subscribe message: unknown fields {', '.join(unknown)}")
    return Subscription(
        tuple(sorted(set(message.fields), key=FIELD_ORDER.__getitem__)), message.rate_hz
    )


def _parse_rate(text: str | None) -> float | None:
    if text is None or text == "":
        return None
    rate = float(text)  # ValueError for junk
    if not (math.isfinite(rate) and rate > 0):
        raise ValueError(f"rate must be a positive number of Hz, got {text}")
    return rate


@router.websocket("/api/v1/robots/{name}/stream")
async def robot_stream(websocket: WebSocket, name: str) -> None:
    await _stream(websocket, name)


@router.websocket("/api/v1/stream")
async def stream(websocket: WebSocket) -> None:
    """Deprecated: the first robot's stream."""
    await _stream(websocket, None)


async def _stream(websocket: WebSocket, name: str | None) -> None:
    service = get_service(websocket)
    session = service.sessions.get(session_token(websocket))
    await websocket.accept()
    try:
        robot = service.default_robot if name is None else service.robot(name)
    except UnknownRobotError as error:
        await websocket.close(CLOSE_UNKNOWN_ROBOT, str(error)[:120])
        return
    if service.settings.web.view_requires_login and session is None:
        await websocket.close(CLOSE_LOGIN_REQUIRED, "login required")
        return
    try:
        rate_hz = _parse_rate(websocket.query_params.get("rate"))
    except ValueError as error:
        await websocket.close(CLOSE_BAD_REQUEST, f"bad rate: {error}"[:120])
        return

    abort_transport: Callable[[], None] | None = websocket.scope.get(ABORT_KEY)

    async def abort(reason: str) -> None:
        if abort_transport is not None:
            abort_transport()
            return
        with contextlib.suppress(Exception):
            async with asyncio.timeout(1.0):
                await websocket.close(CLOSE_STALLED, reason)

    hello = await robot.hello(rate_hz)
    # Control as this stream's session sees it: "held by you in another window" is
    # holder.session != hello.session with the same user.
    hello["control"] = robot.control.status_for(session)
    hello["session"] = session.id if session is not None else None
    hello["alarms"] = robot.alarms.current()  # the banner from the first message on
    hello["cell_alarms"] = service.cell_alarms()  # the other robots' too (then each status)
    hello["kiosk"] = service.settings.kiosk.kiosk_hello()  # a kiosk's plot window and shifts
    client = robot.hub.add_client(
        websocket.send_text,
        abort,
        rate_hz,
        hello,
        session_id=session.id if session is not None else None,
        client=f"{client_address(websocket)}:{websocket.client.port if websocket.client else 0}",
        send_plain=websocket.scope.get(SEND_PLAIN_KEY),
        write_now=websocket.scope.get(WRITE_TEXT_NOW_KEY),
    )
    service.websocket_opened(session, robot)
    ended: asyncio.Future[str] = asyncio.get_running_loop().create_future()

    def session_ended(reason: str) -> None:
        if not ended.done():
            ended.set_result(reason)

    unwatch = service.sessions.watch(session, session_ended) if session is not None else None
    reading = asyncio.create_task(
        _read_subscriptions(websocket, robot.hub, client), name="stream-read"
    )
    waiting: list[asyncio.Future[Any]] = [reading, ended]
    try:
        await asyncio.wait(waiting, return_when=asyncio.FIRST_COMPLETED)
    finally:
        if unwatch is not None:
            unwatch()
        reading.cancel()
        with contextlib.suppress(asyncio.CancelledError, Exception):
            await reading  # the client's disconnect (or its error) ends the stream either way
        await robot.hub.remove_client(client)  # no frame is sent after the close below
        if ended.done():
            reason = close_reason(f"session ended: {ended.result()}")
            try:
                async with asyncio.timeout(1.0):
                    await websocket.close(CLOSE_SESSION_ENDED, reason)
            except Exception:  # gone meanwhile, or not reading: its connection is cut instead
                if abort_transport is not None:
                    abort_transport()
        else:
            ended.cancel()
        service.websocket_closed(session, robot)


async def _read_subscriptions(
    websocket: WebSocket, hub: WebSocketFanOut, client: StreamClient
) -> None:
    """The client's ``subscribe`` messages until it disconnects; a bad one closes the stream
    with 4400 and why (the client's frames stop before the close)."""
    while True:
        message = await websocket.receive()
        if message["type"] == "websocket.disconnect":
            return
        data = message.get("text") or message.get("bytes") or b""
        try:
            subscription = parse_subscription(data)
        except BadSubscriptionError as error:
            await hub.remove_client(client)
            with contextlib.suppress(Exception):
                async with asyncio.timeout(1.0):
                    await websocket.close(CLOSE_BAD_REQUEST, close_reason(str(error)))
            return
        hub.subscribe(client, subscription)

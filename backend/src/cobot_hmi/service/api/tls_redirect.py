"""Layer: service. The plain-HTTP listener beside HTTPS (``--http-redirect-port``): it answers
every request with a redirect to the same path over HTTPS, and does nothing else.

No application behind it: no page, no API, no session cookie ever crosses it in the clear
(the cookie is ``Secure``, a browser does not send it here). A request whose ``Host`` is not
one the service answers to (``allowed_hosts``, the same check as HTTPS's) gets 400, so the
listener cannot be made to redirect anywhere else. The request head is parsed by ``h11``
(uvicorn's HTTP/1.1 parser); one request per connection, which is closed after the answer; a
connection that sends no complete head within ``HEAD_TIMEOUT_S`` or more than
``MAX_HEAD_BYTES`` is closed. GET and HEAD get 301 (what browsers and crawlers remember), any
other method 308 (the method and body kept). Imports only ``security`` of the project.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import AsyncIterator
from typing import Final

import h11

from cobot_hmi.service.api.security import host_allowed

log = logging.getLogger(__name__)

HEAD_TIMEOUT_S: Final = 10.0
MAX_HEAD_BYTES: Final = 16 * 1024


def location(host_header: str, target: str, https_port: int) -> str:
    """Where a request for ``target`` with ``Host: host_header`` goes over HTTPS."""
    text = host_header.strip()
    if text.startswith("["):  # [::1]:8080
        name = text[: text.find("]") + 1]
    else:
        name = text.rsplit(":", 1)[0] if text.count(":") == 1 else text
    port = "" if https_port == 443 else f":{https_port}"
    path = target if target.startswith("/") else "/"
    return f"https://{name}{port}{path}"


class _Redirect(asyncio.Protocol):
    def __init__(self, https_port: int, allowed_hosts: tuple[str, ...]) -> None:
        self.https_port = https_port
        self.allowed_hosts = allowed_hosts
        self.connection = h11.Connection(h11.SERVER, max_incomplete_event_size=MAX_HEAD_BYTES)
        self.transport: asyncio.Transport | None = None
        self.timer: asyncio.TimerHandle | None = None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        assert isinstance(transport, asyncio.Transport)
        self.transport = transport
        self.timer = asyncio.get_running_loop().call_later(HEAD_TIMEOUT_S, transport.abort)

    def connection_lost(self, exc: Exception | None) -> None:
        if self.timer is not None:
            self.timer.cancel()

    def data_received(self, data: bytes) -> None:
        try:
            self.connection.receive_data(data)
            event = self.connection.next_event()
        except h11.RemoteProtocolError:
            self._answer(400, b"bad request")
            return
        if isinstance(event, h11.Request):
            host = dict(event.headers).get(b"host", b"").decode("latin-1")
            if not host_allowed(host or None, self.allowed_hosts):
                self._answer(400, b"host not allowed")
                return
            target = event.target.decode("latin-1")
            status = 301 if event.method in (b"GET", b"HEAD") else 308
            self._answer(status, b"", location(host, target, self.https_port))

    def _answer(self, status: int, body: bytes, where: str | None = None) -> None:
        assert self.transport is not None
        headers = [("content-length", str(len(body))), ("connection", "close")]
        if where is not None:
            headers.append(("location", where))
        try:
            out = self.connection.send(h11.Response(status_code=status, headers=headers)) or b""
            if body:
                out += self.connection.send(h11.Data(data=body)) or b""
            out += self.connection.send(h11.EndOfMessage()) or b""
        except h11.LocalProtocolError:  # the request was not readable enough to answer
            out = b"HTTP/1.1 400 Bad Request\r\ncontent-length: 0\r\nconnection: close\r\n\r\n"
        self.transport.write(out)
        self.transport.close()


@contextlib.asynccontextmanager
async def redirect_listener(
    host: str, port: int, https_port: int, allowed_hosts: tuple[str, ...]
) -> AsyncIterator[asyncio.Server]:
    """The redirecting listener on ``host:port`` while the block runs."""
    loop = asyncio.get_running_loop()
    server = await loop.create_server(
        lambda: _Redirect(https_port, allowed_hosts), host, port, reuse_address=True
    )
    log.info("HTTP on %s:%d redirects to HTTPS on port %d", host, port, https_port)
    try:
        yield server
    finally:
        server.close()
        await server.wait_closed()

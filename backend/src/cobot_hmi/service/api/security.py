"""Layer: service. The HTTP-level defences, as pure ASGI middlewares in front of the routes.

Outermost first (``install``):

1. ``SecurityHeaders``: every HTTP answer carries a Content-Security-Policy (which also forbids
   framing: ``frame-ancestors 'none'``), ``X-Frame-Options: DENY``, ``X-Content-Type-Options:
   nosniff`` and ``Referrer-Policy: no-referrer``, refusals of the middlewares below included.
2. ``HostCheck``: a ``Host`` header outside the allowed hosts is refused (400 for HTTP, 403
   for a WebSocket handshake). By default the allowed hosts are IP literals, ``localhost``
   and this machine's host name: a DNS name that an attacker points at the HMI (DNS
   rebinding) is not one of them.
3. ``BodyLimit``: a body longer than ``max_body_bytes`` is refused with 413 before anything
   reads it: at once from ``Content-Length``; otherwise the body is read by this middleware,
   at most one byte past the limit and within ``http_idle_timeout_s`` (else 408), before the
   routes see it. The rest of a refused body is read and thrown away (up to
   ``DISCARD_BYTES``) before the connection closes, so the client gets the 413, not a reset.
4. ``CrossSiteCheck``: a request that can change something (any method but GET, HEAD,
   OPTIONS) must come from the HMI's own pages or from a non-browser client. Browsers say where
   a request comes from (``Origin``, else ``Sec-Fetch-Site``); it must be the HMI's own origin
   (scheme, host and port: ``http://127.0.0.1:8001`` is another origin than ``…:8000``) or one
   of ``allowed_origins``. Its body must be JSON (``Content-Type: application/json``): an HTML
   form can post only form encodings and text, so a form on another site can never make a
   valid write. A WebSocket handshake's ``Origin`` is checked against the same origins.
   Scripts (no ``Origin``, no ``Sec-Fetch-Site``) pass when they authenticate with a bearer
   token (which no other site can make a browser send) or not at all; the session cookie
   without either header is refused, since only a browser sends it by itself.
5. ``AnonymousWriteGate``: a changing request to the API (``/api/…`` except login and logout)
   without a live session is refused with 401 here, before any route or database work; each
   client address has a token-bucket budget for such refusals, beyond which it gets 429.

Every refusal is a JSON ``{"detail": {"reason": …}}`` as the routes' own (docs/api.md), and
is counted in ``SecurityCounters`` (``/metrics``, ``service.api.metrics``). Imports only ``auth``
and ``deps`` (the session cookie and token).
"""

from __future__ import annotations

import asyncio
import contextlib
import ipaddress
import math
import re
import socket
import time
from collections import Counter, OrderedDict
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Final

import orjson
from starlette.requests import HTTPConnection
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from cobot_hmi.service.access.auth import SESSION_COOKIE
from cobot_hmi.service.api.deps import session_token
from cobot_hmi.service.api.tls import HSTS_HEADER

if TYPE_CHECKING:
    from fastapi import FastAPI

    from cobot_hmi.service.web.web_settings import WebSettings

SAFE_METHODS: Final = frozenset({"GET", "HEAD", "OPTIONS"})

CSP: Final = "; ".join(
    (
        "default-src 'self'",
        "script-src 'self'",
        # Plotly sets style attributes and inserts <style> elements as it draws.
        "style-src 'self' 'unsafe-inline'",
        "img-src 'self' data: blob:",
        "font-src 'self' data:",
        # The stream: 'self' covers ws:/wss: of the same host and port in CSP Level 3; older
        # browsers need them named, which SecurityHeaders does per request.
        "connect-src 'self'",
        "object-src 'none'",
        "base-uri 'self'",
        "form-action 'self'",
        "frame-ancestors 'none'",
    )
)
DOCS_CSP: Final = "; ".join(
    (
        "default-src 'self'",
        # FastAPI's /docs and /redoc pages load Swagger UI / ReDoc from jsDelivr and start it
        # from an inline script.
        "script-src 'self' 'unsafe-inline' https://cdn.jsdelivr.net",
        "style-src 'self' 'unsafe-inline' https://cdn.jsdelivr.net https://fonts.googleapis.com",
        "font-src 'self' data: https://fonts.gstatic.com",
        "img-src 'self' data: https://fastapi.tiangolo.com https://cdn.redoc.ly",
        "worker-src 'self' blob:",
        "connect-src 'self'",
        "object-src 'none'",
        "base-uri 'self'",
        "frame-ancestors 'none'",
    )
)
_DOCS_PATHS: Final = ("/docs", "/redoc")
_PLAIN_HOST: Final = re.compile(r"^(?:[a-z0-9.-]+|\[[0-9a-f:.]+\])(?::[0-9]{1,5})?$")
"""A ``Host`` header safe to repeat inside the CSP (nothing but a name or address and port)."""


def _csp_for(host: str | None) -> bytes:
    if host is not None and _PLAIN_HOST.fullmatch(host.strip().lower()):
        name = host.strip().lower()
        return CSP.replace(
            "connect-src 'self'", f"connect-src 'self' ws://{name} wss://{name}"
        ).encode()
    return CSP.encode()


REFUSAL_REASONS: Final = (
    "host",
    "body_too_large",
    "body_too_slow",
    "cross_site",
    "content_type",
    "anonymous_write",
    "anonymous_throttled",
    "websocket_origin",
)
"""Why a request was refused: the keys of ``SecurityCounters.refusals`` (``/metrics`` writes
each, zero or not)."""


@dataclass(slots=True)
class SecurityCounters:
    """Refusals by reason (``REFUSAL_REASONS``), for ``/metrics`` (``service.api.metrics``)."""

    refusals: Counter[str] = field(default_factory=Counter)


# --------------------------------------------------------------------------- answers


def _error_answer(
    reason: str, headers: Iterable[tuple[str, str]]
) -> tuple[list[tuple[bytes, bytes]], bytes]:
    """The raw headers and the body of the API's error answer ``{"detail": {"reason": …}}``."""
    body = orjson.dumps({"detail": {"reason": reason}})
    raw_headers = [
        (b"content-type", b"application/json"),
        (b"content-length", str(len(body)).encode()),
        *((k.lower().encode("latin-1"), v.encode("latin-1")) for k, v in headers),
    ]
    return raw_headers, body


async def _refuse(
    scope: Scope,
    send: Send,
    status: int,
    reason: str,
    headers: Iterable[tuple[str, str]] = (),
) -> None:
    """Answer ``status`` with the API's error body (HTTP), or deny a WebSocket handshake."""
    raw_headers, body = _error_answer(reason, headers)
    if scope["type"] == "websocket":
        if "websocket.http.response" in scope.get("extensions", {}):
            await send(
                {"type": "websocket.http.response.start", "status": status, "headers": raw_headers}
            )
            await send({"type": "websocket.http.response.body", "body": body})
        else:  # a close before accept is answered 403 by the server
            await send({"type": "websocket.close", "code": 1008, "reason": reason[:120]})
        return
    await send({"type": "http.response.start", "status": status, "headers": raw_headers})
    await send({"type": "http.response.body", "body": body})


def _header(scope: Scope, name: bytes) -> str | None:
    for key, value in scope["headers"]:
        if key == name:
            return str(value.decode("latin-1"))
    return None


# --------------------------------------------------------------------------- 1. headers


class SecurityHeaders:
    """Adds the security headers to every HTTP answer (unless a route set its own)."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        if scope["path"].startswith(_DOCS_PATHS):
            csp = DOCS_CSP.encode()
        else:
            csp = _csp_for(_header(scope, b"host"))
        extra: tuple[tuple[bytes, bytes], ...] = (
            (b"content-security-policy", csp),
            (b"x-frame-options", b"DENY"),
            (b"x-content-type-options", b"nosniff"),
            (b"referrer-policy", b"no-referrer"),
        )
        if scope.get("scheme") == "https":  # HSTS only over HTTPS (RFC 6797 §7.2; tls.py)
            extra = (*extra, (b"strict-transport-security", HSTS_HEADER))

        async def send_with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                headers = list(message.get("headers", ()))
                present = {k.lower() for k, _ in headers}
                headers.extend((k, v) for k, v in extra if k not in present)
                message = {**message, "headers": headers}
            await send(message)

        await self.app(scope, receive, send_with_headers)


# --------------------------------------------------------------------------- 2. host


def _host_name(host_header: str) -> str:
    """The host of a ``Host`` header without its port, lower case, IPv6 without brackets."""
    text = host_header.strip().lower()
    if text.startswith("["):
        return text[1 : text.find("]")] if "]" in text else text
    return text.rsplit(":", 1)[0] if text.count(":") == 1 else text


def _is_ip_literal(name: str) -> bool:
    try:
        ipaddress.ip_address(name)
    except ValueError:
        return False
    return True


def default_allowed_hosts() -> tuple[str, ...]:
    """IP literals (``"ip"``), ``localhost`` and this machine's names."""
    names = {"ip", "localhost"}
    hostname = socket.gethostname().lower()
    if hostname:
        names |= {hostname, f"{hostname}.local"}
    return tuple(sorted(names))


def host_allowed(host_header: str | None, allowed: tuple[str, ...]) -> bool:
    """``allowed`` holds names, ``*.suffix`` patterns, ``ip`` (any IP literal) or ``*``."""
    if "*" in allowed:
        return True
    if not host_header:
        return False
    name = _host_name(host_header)
    for pattern in allowed:
        if pattern == "ip":
            if _is_ip_literal(name):
                return True
        elif pattern.startswith("*."):
            if name.endswith(pattern[1:]):
                return True
        elif name == pattern:
            return True
    return False


class HostCheck:
    def __init__(self, app: ASGIApp, allowed: tuple[str, ...], counters: SecurityCounters):
        self.app = app
        self.allowed = tuple(h.strip().lower() for h in allowed if h.strip())
        self.counters = counters

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] in ("http", "websocket"):
            host = _header(scope, b"host")
            if not host_allowed(host, self.allowed):
                self.counters.refusals["host"] += 1
                status = 400 if scope["type"] == "http" else 403
                await _refuse(
                    scope, send, status, f"host {host!r} is not served here (allowed_hosts)"
                )
                return
        await self.app(scope, receive, send)


# --------------------------------------------------------------------------- 3. body limit

DISCARD_BYTES: Final = 16 * 1024 * 1024
"""How much of a refused body is read and thrown away before the connection closes (the time
bound is ``http_idle_timeout_s``); a body announced longer is not waited for."""


class BodyLimit:
    """Bounds request bodies to ``max_bytes`` and ``timeout_s`` before any route reads them.

    A body is read here whole (at most one byte past the limit) and handed to the routes as
    one message, so no route ever waits on a client: one that announces a large body is
    refused at once from its ``Content-Length``, one that sends too much (chunked) as soon as
    it passes the limit, one that sends slowly (a connection held busy for ever) with 408 once
    ``timeout_s`` has passed.
    """

    def __init__(
        self,
        app: ASGIApp,
        max_bytes: int,
        timeout_s: float,
        counters: SecurityCounters,
        discard_bytes: int = DISCARD_BYTES,
    ) -> None:
        self.app = app
        self.max_bytes = max_bytes
        self.timeout_s = timeout_s
        self.counters = counters
        self.discard_bytes = discard_bytes

    async def _refuse_and_close(self, scope: Scope, send: Send, status: int, reason: str) -> None:
        self.counters.refusals["body_too_large" if status == 413 else "body_too_slow"] += 1
        # The rest of the body is never read: the connection cannot carry another request.
        await _refuse(scope, send, status, reason, [("connection", "close")])

    async def _too_large(self, receive: Receive, send: Send, *, received: int, more: bool) -> None:
        """413 at once, then (``more``) the rest of the body read and thrown away, up to
        ``discard_bytes`` in all and within ``timeout_s``, before the answer ends and the
        connection closes. A socket closed with unread data is reset by the kernel, and a
        client still sending (python-requests over TLS: one time in two with a 2 MB body) then
        loses the 413 and reports the reset instead."""
        self.counters.refusals["body_too_large"] += 1
        raw_headers, body = _error_answer(
            f"request body larger than {self.max_bytes} bytes (max_body_bytes)",
            [("connection", "close")],
        )
        await send({"type": "http.response.start", "status": 413, "headers": raw_headers})
        await send({"type": "http.response.body", "body": body, "more_body": True})
        with contextlib.suppress(TimeoutError):
            async with asyncio.timeout(self.timeout_s):
                while more and received <= self.discard_bytes:
                    message = await receive()
                    received += len(message.get("body", b""))
                    more = message["type"] == "http.request" and message.get("more_body", False)
        await send({"type": "http.response.body", "body": b"", "more_body": False})

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        length = _header(scope, b"content-length")
        if length is not None:
            if not (length.isascii() and length.strip().isdigit()):
                await _refuse(scope, send, 400, f"bad Content-Length {length[:40]!r}")
                return
            if int(length) > self.max_bytes:
                # A body announced past the discard bound is not waited for (1 GiB, say).
                await self._too_large(
                    receive, send, received=0, more=int(length) <= self.discard_bytes
                )
                return
            if int(length) == 0:
                await self.app(scope, receive, send)
                return
        elif _header(scope, b"transfer-encoding") is None:
            await self.app(scope, receive, send)  # no body
            return
        chunks: list[bytes] = []
        size = 0
        try:
            async with asyncio.timeout(self.timeout_s):
                while True:
                    message = await receive()
                    if message["type"] != "http.request":
                        return  # the client went away
                    chunk = message.get("body", b"")
                    size += len(chunk)
                    if size > self.max_bytes:
                        break
                    chunks.append(chunk)
                    if not message.get("more_body", False):
                        break
        except TimeoutError:
            await self._refuse_and_close(
                scope,
                send,
                408,
                f"request body not complete within {self.timeout_s:g} s (http_idle_timeout_s)",
            )
            return
        if size > self.max_bytes:
            await self._too_large(
                receive, send, received=size, more=message.get("more_body", False)
            )
            return
        replayed = False

        async def replay() -> Message:
            nonlocal replayed
            if not replayed:
                replayed = True
                return {"type": "http.request", "body": b"".join(chunks), "more_body": False}
            return await receive()

        await self.app(scope, replay, send)


# --------------------------------------------------------------------------- 4. cross-site


def _origin_of(scope: Scope, host: str) -> str:
    scheme = {"ws": "http", "wss": "https"}.get(scope.get("scheme", "http"), scope["scheme"])
    return f"{scheme}://{host.strip().lower()}"


def _normalize_origin(origin: str) -> str:
    text = origin.strip().lower().rstrip("/")
    for scheme, port in (("http://", ":80"), ("https://", ":443")):
        if text.startswith(scheme) and text.endswith(port):
            return text[: -len(port)]
    return text


def _cookie_session_only(scope: Scope) -> bool:
    """Whether the request carries the session cookie and no bearer token."""
    connection = HTTPConnection(scope)
    if not connection.cookies.get(SESSION_COOKIE):
        return False
    scheme, _, token = connection.headers.get("authorization", "").partition(" ")
    return not (scheme.lower() == "bearer" and token.strip())


class CrossSiteCheck:
    """Changing requests and WebSocket handshakes only from the HMI's own origin (or an
    allowed one); changing requests with a body only as JSON."""

    def __init__(
        self, app: ASGIApp, allowed_origins: tuple[str, ...], counters: SecurityCounters
    ) -> None:
        self.app = app
        self.allowed_origins = frozenset(_normalize_origin(o) for o in allowed_origins if o)
        self.counters = counters

    def _origin_refusal(self, scope: Scope) -> str | None:
        """Why the request's origin is refused, or ``None``."""
        origin = _header(scope, b"origin")
        if origin is not None:
            own = _normalize_origin(_origin_of(scope, _header(scope, b"host") or ""))
            normalized = _normalize_origin(origin)
            if normalized == own or normalized in self.allowed_origins:
                return None
            return f"cross-origin request from {origin[:80]!r} refused (allowed_origins)"
        site = _header(scope, b"sec-fetch-site")
        if site is not None:
            if site.strip().lower() not in ("same-origin", "none"):
                return f"cross-site request ({site[:20]}) refused"
            return None
        if _cookie_session_only(scope):
            # Only a browser sends the cookie by itself, and every browser of today says where
            # its request comes from: one that does not is treated as foreign.
            return (
                "a request with the session cookie must come from the HMI's own page (Origin "
                "or Sec-Fetch-Site); scripts send Authorization: Bearer"
            )
        return None

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "websocket":
            refusal = self._origin_refusal(scope)
            if refusal is not None:
                self.counters.refusals["websocket_origin"] += 1
                await _refuse(scope, send, 403, refusal)
                return
        elif scope["type"] == "http" and scope["method"] not in SAFE_METHODS:
            refusal = self._origin_refusal(scope)
            if refusal is not None:
                self.counters.refusals["cross_site"] += 1
                await _refuse(scope, send, 403, refusal)
                return
            content_type = _header(scope, b"content-type")
            has_body = _header(scope, b"transfer-encoding") is not None or (
                _header(scope, b"content-length") or "0"
            ).strip() not in ("", "0")
            media = (content_type or "").split(";", 1)[0].strip().lower()
            if (content_type is not None or has_body) and not (
                media == "application/json"
                or (media.startswith("application/") and media.endswith("+json"))
            ):
                self.counters.refusals["content_type"] += 1
                await _refuse(
                    scope,
                    send,
                    415,
                    f"a request body must be JSON (Content-Type: application/json), "
                    f"got {content_type[:60] if content_type else 'none'!r}",
                )
                return
        await self.app(scope, receive, send)


# --------------------------------------------------------------------------- 5. anonymous writes


class TokenBuckets:
    """A token bucket per key (client address): ``rate_per_s`` tokens a second, at most
    ``burst``. At most ``max_keys`` buckets are kept; the least recently used goes first
    (a full bucket forgotten is the same as a new one)."""

    def __init__(self, rate_per_s: float, burst: int, max_keys: int = 10_000) -> None:
        self.rate_per_s = rate_per_s
        self.burst = burst
        self.max_keys = max_keys
        self._buckets: OrderedDict[str, tuple[float, float]] = OrderedDict()  # tokens, at

    def take(self, key: str) -> float:
        """Take a token for ``key``: 0 if there was one, else seconds until there is."""
        now = time.monotonic()
        tokens, at = self._buckets.pop(key, (float(self.burst), now))
        tokens = min(float(self.burst), tokens + (now - at) * self.rate_per_s)
        wait_s = 0.0
        if tokens >= 1.0:
            tokens -= 1.0
        else:
            wait_s = (1.0 - tokens) / self.rate_per_s if self.rate_per_s > 0 else math.inf
        self._buckets[key] = (tokens, now)
        while len(self._buckets) > self.max_keys:
            self._buckets.popitem(last=False)
        return wait_s


_OPEN_API_PATHS: Final = ("/api/v1/auth/",)
"""Changing requests that work without a session: login (and logout, which ends one)."""


class AnonymousWriteGate:
    """401 for a changing API request without a live session, before any route runs; 429
    once a client address has used up its budget of such refusals."""

    def __init__(self, app: ASGIApp, buckets: TokenBuckets, counters: SecurityCounters) -> None:
        self.app = app
        self.buckets = buckets
        self.counters = counters

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if (
            scope["type"] == "http"
            and scope["method"] not in SAFE_METHODS
            and scope["path"].startswith("/api/")
            and not scope["path"].startswith(_OPEN_API_PATHS)
            and not self._has_session(scope)
        ):
            client = scope.get("client")
            wait_s = self.buckets.take(client[0] if client else "")
            if wait_s > 0:
                self.counters.refusals["anonymous_throttled"] += 1
                seconds = max(1, math.ceil(min(wait_s, 3600.0)))
                await _refuse(
                    scope,
                    send,
                    429,
                    f"too many requests without login: try again in {seconds} s",
                    [("retry-after", str(seconds))],
                )
                return
            self.counters.refusals["anonymous_write"] += 1
            await _refuse(scope, send, 401, "login required", [("www-authenticate", "Bearer")])
            return
        await self.app(scope, receive, send)

    @staticmethod
    def _has_session(scope: Scope) -> bool:
        connection = HTTPConnection(scope)
        service = scope["app"].state.service
        return service.sessions.get(session_token(connection)) is not None


# --------------------------------------------------------------------------- wiring


@dataclass(frozen=True, slots=True)
class SecurityPolicy:
    """What ``install`` needs (from the service settings)."""

    max_body_bytes: int = 64 * 1024
    body_timeout_s: float = 10.0
    allowed_hosts: tuple[str, ...] = field(default_factory=default_allowed_hosts)
    allowed_origins: tuple[str, ...] = ()
    anonymous_writes_per_s: float = 1.0
    anonymous_write_burst: int = 20


def policy_from_settings(settings: WebSettings) -> SecurityPolicy:
    return SecurityPolicy(
        max_body_bytes=settings.max_body_bytes,
        body_timeout_s=settings.http_idle_timeout_s,
        allowed_hosts=tuple(settings.allowed_hosts) or default_allowed_hosts(),
        allowed_origins=tuple(settings.allowed_origins),
        anonymous_writes_per_s=settings.anonymous_writes_per_s,
        anonymous_write_burst=settings.anonymous_write_burst,
    )


def install(app: FastAPI, policy: SecurityPolicy) -> SecurityCounters:
    """Add the middlewares (outermost last added); the counters they share."""
    counters = SecurityCounters()
    buckets = TokenBuckets(policy.anonymous_writes_per_s, policy.anonymous_write_burst)
    app.add_middleware(AnonymousWriteGate, buckets=buckets, counters=counters)
    app.add_middleware(CrossSiteCheck, allowed_origins=policy.allowed_origins, counters=counters)
    app.add_middleware(
        BodyLimit,
        max_bytes=policy.max_body_bytes,
        timeout_s=policy.body_timeout_s,
        counters=counters,
    )
    app.add_middleware(HostCheck, allowed=policy.allowed_hosts, counters=counters)
    app.add_middleware(SecurityHeaders)
    return counters


__all__ = [
    "CSP",
    "REFUSAL_REASONS",
    "SecurityCounters",
    "SecurityPolicy",
    "TokenBuckets",
    "host_allowed",
    "install",
    "policy_from_settings",
]

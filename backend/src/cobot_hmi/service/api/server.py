"""Layer: service. Running the app on uvicorn, as ``cobot-hmi serve`` and ``demo`` do.

uvicorn handles SIGINT/SIGTERM: it stops accepting, closes the WebSockets, runs the app's
lifespan shutdown (which releases control and sends the Forward Close), then re-raises the
signal, which the CLI turns into its exit status.
"""

from __future__ import annotations

import contextlib
import socket
import sys
from collections.abc import Callable
from typing import Any, Final, TypeVar

import uvicorn

from cobot_hmi import native
from cobot_hmi.eventloop import freeze_startup_heap
from cobot_hmi.service.api import http_limits, ws_deflate
from cobot_hmi.service.api.app import create_app
from cobot_hmi.service.api.security import policy_from_settings
from cobot_hmi.service.api.tls import ReloadingContext
from cobot_hmi.service.api.tls_redirect import redirect_listener
from cobot_hmi.service.runtime import Service
from cobot_hmi.service.service_settings import ServiceSettings
from cobot_hmi.service.web.tls_settings import TlsSettings
from cobot_hmi.service.web.web_settings import WebSettings

SWITCH_INTERVAL_S: Final = 0.005
"""The GIL hand-over deadline with the C pump: CPython's default. The pump's thread sends every
O→T packet on time and stamps every T→O packet with the kernel's receive time without the GIL,
so a thread holding the GIL this long delays no packet; the Python threads then hand the GIL
over ten times less often than at ``PURE_PUMP_SWITCH_INTERVAL_S``, and each hand-over costs
CPU (a futex wake-up, a cold cache): bench/fanout at 32 robots with every door measured the
service's CPU per robot-frame 111 µs / 95 µs (with / without clients) against 120 µs / 110 µs
at 0.5 ms (load average 6.5 both, separate runs)."""
PURE_PUMP_SWITCH_INTERVAL_S: Final = 0.0005
"""The GIL hand-over deadline with the pure-Python pump (no C extension): that pump's thread
needs the GIL for every packet it sends, so a busy web thread must hand it over within 0.5 ms,
not CPython's 5 ms, half an RPI of 10 ms (docs/protocol.md, "Timing")."""


def uvicorn_config(
    app: Any, web: WebSettings, tls_settings: TlsSettings, **overrides: Any
) -> uvicorn.Config:
    """uvicorn's configuration of the HTTP door: the web service's address and bounds (``web``)
    and HTTPS (``tls_settings``)."""
    connection_counters = http_limits.ConnectionCounters()
    state = getattr(app, "state", None)
    if state is not None:  # for /metrics
        state.connection_counters = connection_counters
    options: dict[str, Any] = {
        "host": web.host,
        "port": web.port,
        "lifespan": "on",
        # permessage-deflate (RFC 7692) when the client offers it, as browsers do: a phone's
        # stream shrinks several times (docs/api.md). Paid per client per message (each has
        # its own compressor), after the hub has serialized once per group; so a stream of
        # every field sends its frames uncompressed (ws_deflate.StreamWebSocketProtocol).
        "ws_per_message_deflate": True,
        "ws": ws_deflate.StreamWebSocketProtocol,
        "timeout_graceful_shutdown": 3,
        "access_log": False,
        "log_level": "info",
        # Bounds (service/api/http_limits.py, docs/operations.md "Security"). X-Forwarded-For and
        # -Proto only from the configured proxies: uvicorn's default trusts 127.0.0.1, which
        # let any local client forge its address.
        "proxy_headers": bool(web.trusted_proxies),
        "forwarded_allow_ips": list(web.trusted_proxies),
        "http": http_limits.bounded_h11_protocol(
            max_connections=http_limits.connection_cap(web.http_max_connections),
            idle_timeout_s=web.http_idle_timeout_s,
            counters=connection_counters,
        ),
        "backlog": web.http_backlog,
        "timeout_keep_alive": web.http_keep_alive_s,
        "h11_max_incomplete_event_size": web.http_max_header_bytes,
        "ws_max_size": web.max_body_bytes,
    }
    if tls_settings.tls_cert is not None and tls_settings.tls_key is not None:
        # HTTPS and WSS (service/api/tls.py): TLS 1.2 at least, the certificate re-read when
        # its files change; TlsError here when they cannot be used.
        tls = ReloadingContext(tls_settings.tls_cert, tls_settings.tls_key)
        options["ssl_context_factory"] = lambda _config, _default: tls.listener
        if state is not None:
            state.tls = tls
    options.update(overrides)
    return uvicorn.Config(app, **options)


def switch_interval_s() -> float:
    """The GIL hand-over deadline for this process's cyclic pump (``COBOT_HMI_PUMP``)."""
    try:
        _, implementation = native.pump_class()
    except (ValueError, native.PumpUnavailableError):
        return PURE_PUMP_SWITCH_INTERVAL_S  # the first endpoint will say why, and stop there
    return SWITCH_INTERVAL_S if implementation == "native" else PURE_PUMP_SWITCH_INTERVAL_S


def prepare_process() -> None:
    """Process-wide settings for a service process (not for a library import)."""
    sys.setswitchinterval(switch_interval_s())


SettingsT = TypeVar("SettingsT", bound=ServiceSettings)
"""The settings the service is built of: its own, or a class composed above it with more."""


async def serve(
    settings: SettingsT,
    build: Callable[[SettingsT], Service],
    *,
    sockets: list[socket.socket] | None = None,
) -> None:
    """Run the service ``build`` makes of ``settings`` (``cobot_hmi.composition``) until a
    signal stops it; on ``sockets`` (already bound, as the demo binds its HTTP address before
    it prints a password) instead of binding ``host:port``."""
    service = build(settings)
    app = create_app(service, on_started=freeze_startup_heap)
    server = uvicorn.Server(uvicorn_config(app, settings.web, settings.tls))
    async with contextlib.AsyncExitStack() as stack:
        if settings.tls.http_redirect_port is not None:  # plain HTTP that only redirects to HTTPS
            https_port = sockets[0].getsockname()[1] if sockets else settings.web.port
            allowed = policy_from_settings(settings.web).allowed_hosts
            await stack.enter_async_context(
                redirect_listener(
                    settings.web.host, settings.tls.http_redirect_port, https_port, allowed
                )
            )
        await server.serve(sockets=sockets)

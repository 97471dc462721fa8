"""Layer: service. Bounds on the service's TCP connections: uvicorn's HTTP protocol, bounded.

uvicorn holds a connection that never sends a request for as long as the client keeps it
open, and accepts connections until the process runs out of file descriptors; past that, the
kernel queues new connections that are never accepted, so a thousand idle sockets starve every
real client. ``bounded_h11_protocol`` returns uvicorn's h11 protocol with three bounds:

- a connection must send a complete request head within ``idle_timeout_s`` of connecting or of
  its previous answer (a keep-alive connection trickling bytes included), else it is closed;
- at most ``max_connections`` connections (HTTP and WebSocket) are held: a new one beyond that
  closes the longest-idle HTTP connection (one with no request in progress); if every held
  connection is busy, the new one is closed at once (a refusal);
- the number of file descriptors the process may open caps ``max_connections`` (with room for
  the database, the class 1 sockets and the WebSockets' own needs), see ``connection_cap``.

Closings and refusals are counted in ``ConnectionCounters`` for ``/metrics``. Imports nothing of
the project.
"""

from __future__ import annotations

import asyncio
import resource
from collections import Counter
from dataclasses import dataclass, field
from typing import Any, Final

from uvicorn.protocols.http.h11_impl import H11Protocol

FD_RESERVE: Final = 64
"""File descriptors kept free of HTTP connections: database, class 1 sockets, logs, threads."""


@dataclass(slots=True)
class ConnectionCounters:
    """``idle_closed``: no request head in time; ``evicted``: an idle connection closed to make
    room; ``refused``: a new connection closed because every slot was busy."""

    closed: Counter[str] = field(default_factory=Counter)


def connection_cap(max_connections: int) -> int:
    """``max_connections``, lowered to what the open-files limit leaves room for."""
    soft, _ = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft == resource.RLIM_INFINITY:
        return max_connections
    return max(8, min(max_connections, soft - FD_RESERVE))


def bounded_h11_protocol(
    *, max_connections: int, idle_timeout_s: float, counters: ConnectionCounters
) -> type[asyncio.Protocol]:
    """uvicorn's h11 protocol class with the bounds above (``uvicorn.Config(http=…)``)."""

    class BoundedH11Protocol(H11Protocol):
        _idle_since: float
        _idle_timer: asyncio.TimerHandle | None

        def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
            super().connection_made(transport)
            self._idle_timer = None
            self._arm_idle_timer()
            if len(self.connections) > max_connections:
                self._make_room()

        def _busy(self) -> bool:
            return self.cycle is not None and not self.cycle.response_complete

        def _arm_idle_timer(self) -> None:
            self._idle_since = self.loop.time()
            if self._idle_timer is not None:
                self._idle_timer.cancel()
            self._idle_timer = self.loop.call_later(idle_timeout_s, self._idle_timeout)

        def _cancel_idle_timer(self) -> None:
            if self._idle_timer is not None:
                self._idle_timer.cancel()
                self._idle_timer = None

        def _idle_timeout(self) -> None:
            self._idle_timer = None
            if not self._busy() and not self.transport.is_closing():
                counters.closed["idle_closed"] += 1
                self.transport.abort()

        def _make_room(self) -> None:
            idle = [
                c
                for c in self.connections
                if isinstance(c, BoundedH11Protocol)
                and c is not self
                and not c._busy()
                and not c.transport.is_closing()
            ]
            # Out of the table at once: the loop reports the lost connection only later.
            if idle:
                oldest = min(idle, key=lambda c: c._idle_since)
                counters.closed["evicted"] += 1
                oldest.transport.abort()
                self.connections.discard(oldest)
            else:
                counters.closed["refused"] += 1
                self.transport.abort()
                self.connections.discard(self)

        def data_received(self, data: bytes) -> None:
            super().data_received(data)
            if self._busy():
                self._cancel_idle_timer()  # a request head arrived: its handling has no deadline

        def handle_websocket_upgrade(self, event: Any) -> None:
            self._cancel_idle_timer()  # the WebSocket protocol takes the connection over
            super().handle_websocket_upgrade(event)

        def on_response_complete(self) -> None:
            super().on_response_complete()
            if not self.transport.is_closing():
                self._arm_idle_timer()

        def connection_lost(self, exc: Exception | None) -> None:
            self._cancel_idle_timer()
            super().connection_lost(exc)

    return BoundedH11Protocol

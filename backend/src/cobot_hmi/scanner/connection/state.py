"""Layer: scanner. A class 1 connection's state, its errors and its figures, as the
originator's users see them (``cobot_hmi.scanner.originator`` re-exports them), and
:class:`ConnectionStatus`, the record of that state the originator's parts share: the lifecycle
writes it, the O→T sender reads it (no run without a connection), the originator's users wait
on it.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable
from dataclasses import dataclass
from enum import StrEnum

from cobot_hmi.scanner.t2o_pace import SlowTarget

log = logging.getLogger(__name__)


class ConnectionState(StrEnum):
    IDLE = "idle"
    CONNECTING = "connecting"
    CONNECTED = "connected"
    LOST = "lost"
    REFUSED = "refused"


class ReadOnlyError(Exception):
    """The originator is input-only: it never owns the robot's outputs."""


class NotConnectedError(Exception):
    """No class 1 connection is up."""


@dataclass(frozen=True)
class ConnectionStats:
    state: ConnectionState
    reason: str | None
    packets_in: int
    packets_out: int
    gaps: int
    """T→O packets lost on the way: the CIP sequence count's jumps past one, summed (a
    target sending slower than its grant makes none)."""
    duplicates: int
    """T→O packets repeating the last CIP sequence count (no new data)."""
    late: int
    """T→O frames (new data) received more than 1.5 × the granted T→O API after the frame
    before: after a gap or duplicates, or from a target slower than its grant (``slow_target``
    says when it is that)."""
    malformed: int
    interval_mean_ms: float | None
    interval_p99_ms: float | None
    interval_max_ms: float | None
    last_frame_age_s: float | None
    connected_since: float | None
    """Epoch seconds."""
    stale: int = 0
    """T→O packets older than one already received (out of order), dropped."""
    foreign: int = 0
    """Datagrams dropped for not being this connection's: its connection ID from another
    address than the target's (forged), or an unknown connection ID from the target's address
    (or from anywhere, on a port of the originator's own)."""
    frames: int = 0
    interval_p50_ms: float | None = None
    rpi_us: int | None = None
    """The T→O actual packet interval of the connection (the target's reply)."""
    slow_target: SlowTarget | None = None
    """The target sends T→O less often than it granted (``scanner.t2o_pace``), while it does."""


StateCallback = Callable[[ConnectionState, str | None], None]


class ConnectionStatus:
    """One connection's state and why, told to ``on_state`` once per change, and since when it
    is connected."""

    def __init__(self, on_state: StateCallback | None = None) -> None:
        self.on_state = on_state
        self.state = ConnectionState.IDLE
        self.reason: str | None = None
        self.connected_since: float | None = None
        """Epoch seconds (set by the lifecycle as the first frame arrives, None after the
        teardown)."""
        self._connected = asyncio.Event()

    def set(self, state: ConnectionState, reason: str | None) -> None:
        """The state is now ``state`` for ``reason``: logged when there is a reason, told to
        ``on_state`` (a callback that fails is logged, the connection goes on)."""
        if state is self.state and reason == self.reason:
            return
        self.state = state
        self.reason = reason
        if state is ConnectionState.CONNECTED:
            self._connected.set()
        else:
            self._connected.clear()
        if reason:
            log.info("originator %s: %s", state, reason)
        if self.on_state is not None:
            try:
                self.on_state(state, reason)
            except Exception:
                log.exception("on_state callback failed")

    async def wait_connected(self, timeout_s: float) -> bool:
        """Whether the state is CONNECTED within ``timeout_s`` (and still is when the wait
        ends)."""
        if self.state is ConnectionState.CONNECTED:
            return True
        try:
            await asyncio.wait_for(self._connected.wait(), timeout_s)
        except TimeoutError:
            return False
        state: ConnectionState = self.state  # changed by the supervisor meanwhile
        return state is ConnectionState.CONNECTED

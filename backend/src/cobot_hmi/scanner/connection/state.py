"""Layer: scanner. A class 1 connection's state, its errors and its figures, as the
originator's users see them (``cobot_hmi.scanner.originator`` re-exports them).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from cobot_hmi.scanner.t2o_pace import SlowTarget


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

"""Layer: emulator (no I/O here). Imports ``cobot_hmi.enip`` only.

The target's class 1 connections (instances of the CIP Connection object, Vol 1 §3-4): what a
Forward Open negotiated, the consumed stream's sequence state (``enip.sequence``), and the live
counters the status API shows. The Connection Manager (``connection_manager``) creates them; the
I/O engine (``io_connections``) runs them.
"""

from __future__ import annotations

import asyncio
from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass, field
from enum import StrEnum

from cobot_hmi.enip.connection_manager import connection_timeout_us
from cobot_hmi.enip.epath import ConnectionPath
from cobot_hmi.enip.sequence import SequenceTracker


class ConnectionKind(StrEnum):
    OWNER = "owner"
    INPUT_ONLY = "input-only"
    LISTEN_ONLY = "listen-only"


@dataclass(frozen=True, slots=True)
class ConnectionInfo:
    """A snapshot of one class 1 connection, for a status API."""

    o2t_connection_id: int
    t2o_connection_id: int
    kind: str
    peer: str
    """Where T→O goes, ``host:port``."""
    o2t_rpi_us: int
    t2o_rpi_us: int
    timeout_multiplier: int
    run: bool
    packets_in: int
    packets_out: int
    opened_at: float
    o2t_gaps: int = 0
    o2t_duplicates: int = 0
    o2t_intervals: int = 0
    o2t_interval_p50_ms: float | None = None
    o2t_interval_p99_ms: float | None = None
    o2t_interval_max_ms: float | None = None
    o2t_data_hex: str | None = None
    """The O→T data (after the run/idle header) of the owner's last new packet, run or idle."""
    o2t_data_changes: int = 0
    """New O→T packets whose data differed from the one before (0: every packet so far
    carried ``o2t_data_hex``)."""


@dataclass(eq=False)
class IoConnection:
    """One class 1 connection: its negotiated parameters and its live counters."""

    kind: ConnectionKind
    o2t_id: int
    t2o_id: int
    triplet: tuple[int, int, int]
    peer: tuple[str, int]
    """Where T→O goes: the originator's address and its requested (or the default) port."""
    o2t_rpi_us: int
    t2o_rpi_us: int
    timeout_multiplier: int
    o2t_connection_size: int
    t2o_connection_size: int
    path: ConnectionPath
    """The Forward Open's connection path, decoded."""
    opened_at: float
    """Epoch seconds."""
    run: bool = False
    last_rx: float = 0.0
    """Loop time of the last O→T packet (or of the open, before the first one)."""
    sequence: SequenceTracker = field(default_factory=SequenceTracker)
    """The O→T stream's sequence numbers: which packets are new, duplicates, stale."""
    last_applied: bytes | None = None
    t2o_encap_seq: int = 0
    t2o_cip_seq: int = 0
    packets_in: int = 0
    packets_out: int = 0
    duplicates: int = 0
    o2t_gaps: int = 0
    """O→T packets missing (CIP sequence count jumps), summed."""
    last_o2t_at: float | None = None
    o2t_intervals_ms: deque[float] = field(default_factory=lambda: deque(maxlen=16_384))
    """Recent O→T arrival intervals (new data only), for the status API and the bench."""
    o2t_data: bytes | None = None
    """The data of the owner's last new O→T packet, run or idle."""
    o2t_data_changes: int = 0
    """New O→T packets of the owner whose data differed from the one before."""
    t2o_last_due: float = 0.0
    """Loop time the last T→O packet handed to the cyclic pump is due (a drift-free schedule:
    + RPI each packet)."""
    t2o_last_kind: str = "none"
    """What became of that packet: "sent" (queued as built), "corrupt" (queued cut short by the
    corrupt fault), "dropped" (the drop fault kept it back) or "none"."""
    t2o_streaming: bool = False
    """T→O goes out as a periodic stream of the cyclic pump (the robot's data unchanged between
    our wake-ups and no per-packet fault active), not packet by packet from the queue."""
    t2o_stream_data: bytes | None = None
    """The frame bytes the stream sends."""
    t2o_stream_first_seq: int = 0
    """The encapsulation sequence number of the stream's first packet."""
    t2o_stream_counted: int = 0
    """Packets of the stream already added to ``packets_out``."""
    watchdog: asyncio.TimerHandle | None = None

    def cancel_timers(self) -> None:
        if self.watchdog is not None:
            self.watchdog.cancel()
        self.watchdog = None

    def info(self) -> ConnectionInfo:
        return ConnectionInfo(
            self.o2t_id,
            self.t2o_id,
            str(self.kind),
            f"{self.peer[0]}:{self.peer[1]}",
            self.o2t_rpi_us,
            self.t2o_rpi_us,
            self.timeout_multiplier,
            self.run,
            self.packets_in,
            self.packets_out,
            self.opened_at,
            self.o2t_gaps,
            self.duplicates,
            *_interval_figures(self.o2t_intervals_ms),
            self.o2t_data.hex() if self.o2t_data is not None else None,
            self.o2t_data_changes,
        )

    @property
    def timeout_s(self) -> float:
        """Watchdog: O→T RPI × (4 << multiplier) (CIP Vol 1 §3-5.4.1; docs/protocol.md)."""
        return connection_timeout_us(self.o2t_rpi_us, self.timeout_multiplier) / 1e6

    @property
    def produces(self) -> bool:
        """Whether T→O production depends on this connection alone (not listen-only)."""
        return self.kind is not ConnectionKind.LISTEN_ONLY


def _interval_figures(
    intervals_ms: Iterable[float],
) -> tuple[int, float | None, float | None, float | None]:
    values = sorted(intervals_ms)
    n = len(values)
    if not n:
        return 0, None, None, None
    return n, values[n // 2], values[min(n - 1, int(n * 0.99))], values[-1]

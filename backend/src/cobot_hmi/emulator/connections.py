"""Layer: emulator (no I/O here). Imports ``cobot_hmi.enip`` only.

The target's class 1 connections (instances of the CIP Connection object, Vol 1 §3-4): what a
Forward Open negotiated, the consumed stream's sequence state (``enip.sequence``), and the live
counters the status API shows. The Connection Manager (``connection_manager``) creates them; the
I/O engine (``io_connections``) runs them.
"""

from __future__ import annotations

import asyncio
from collections import deque
from dataclasses import dataclass, field
from enum import StrEnum

from cobot_hmi.enip.connection_manager import connection_timeout_us
from cobot_hmi.enip.epath import ConnectionPath
from cobot_hmi.enip.sequence import SequenceTracker


class ConnectionKind(StrEnum):
    OWNER = "owner"
    INPUT_ONLY = "input-only"
    LISTEN_ONLY = "listen-only"


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

    @property
    def timeout_s(self) -> float:
        """Watchdog: O→T RPI × (4 << multiplier) (CIP Vol 1 §3-5.4.1; docs/protocol.md)."""
        return connection_timeout_us(self.o2t_rpi_us, self.timeout_multiplier) / 1e6

    @property
    def produces(self) -> bool:
        """Whether T→O production depends on this connection alone (not listen-only)."""
        return self.kind is not ConnectionKind.LISTEN_ONLY

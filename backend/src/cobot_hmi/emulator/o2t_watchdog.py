"""Layer: emulator (asyncio I/O). Imports only the emulator's connection table and counters and
the runtime support (``udp_endpoint``).

The target's O→T watchdogs (CIP Vol 1 §3-4, the connection timeout): a connection that has
received no O→T packet for its timeout is closed. While O→T is read at the class 1 engine's
batch wake-ups (``io_connections``), a connection whose timeout spans half a wake-up period or
more is judged at each wake-up (the pump also wakes the engine once O→T has been silent for the
shortest such timeout); every other connection has a timer of its own, re-armed while packets
come. A look more than an O→T RPI late (the loop itself stalled) waits one more RPI for the
packets that may be waiting unread.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable

from cobot_hmi.emulator.connections import IoConnection
from cobot_hmi.emulator.counters import TargetCounters
from cobot_hmi.udp_endpoint import UdpEndpoint


class O2TWatchdogs:
    """The watchdogs of the connections in ``table`` (by O→T connection ID, shared with the
    engine, which owns the socket and the wake-ups: ``udp`` and ``wake_period_s`` read them,
    ``read_due`` reads the O→T waiting, ``close`` closes a connection with its reason)."""

    def __init__(
        self,
        table: dict[int, IoConnection],
        counters: TargetCounters,
        *,
        udp: Callable[[], UdpEndpoint | None],
        wake_period_s: Callable[[], float | None],
        read_due: Callable[[], None],
        close: Callable[[IoConnection, str], None],
    ) -> None:
        self._by_o2t = table
        self._counters = counters
        self._udp = udp
        self._wake_period_s = wake_period_s
        self._read_due = read_due
        self._close = close

    def woke(self) -> None:
        """The pump woke the engine for O→T (read now): per packet, the timers do the rest; in
        batches this is its word that O→T fell silent, so judge the batch-watched connections."""
        udp = self._udp()
        if udp is None or udp.watching:
            return
        self.judge_batch_watched(asyncio.get_running_loop().time(), 0.0)

    def judge_batch_watched(self, now: float, lag_s: float) -> None:
        """The verdict of each connection the batch wake-ups watch (looked at ``lag_s`` late)."""
        for conn in list(self._by_o2t.values()):
            if conn.watchdog is None and self.batch_watches(conn):
                self.verdict(conn, now, lag_s)

    def batch_watches(self, conn: IoConnection) -> bool:
        """Whether the batch wake-ups check this connection (no timer of its own): while O→T is
        read at them, if its timeout spans half of one or more."""
        period_s = self._wake_period_s()
        udp = self._udp()
        return (
            udp is not None
            and not udp.watching
            and period_s is not None
            and conn.timeout_s >= period_s / 2
        )

    def arm(self) -> None:
        """A timer for each connection the batch wake-ups do not watch."""
        loop = asyncio.get_running_loop()
        for conn in self._by_o2t.values():
            if conn.watchdog is None and not self.batch_watches(conn):
                deadline = conn.last_rx + conn.timeout_s
                conn.watchdog = loop.call_at(deadline, self._fire, conn, deadline)

    def _fire(self, conn: IoConnection, armed_for: float) -> None:
        """Armed for the last O→T packet's time + the timeout; re-armed while packets come
        (unless the batch wake-ups took the watch over meanwhile)."""
        conn.watchdog = None
        self._read_due()
        if self._by_o2t.get(conn.o2t_id) is not conn or self.batch_watches(conn):
            return
        now = asyncio.get_running_loop().time()
        deadline = self.verdict(conn, now, now - armed_for)
        if deadline is not None:
            conn.watchdog = asyncio.get_running_loop().call_at(deadline, self._fire, conn, deadline)

    def verdict(self, conn: IoConnection, now: float, lag_s: float) -> float | None:
        """Close the connection if no O→T came for its timeout; else when to look again."""
        timeout_s = conn.timeout_s
        deadline = conn.last_rx + timeout_s
        rpi_s = conn.o2t_rpi_us / 1e6
        if lag_s > rpi_s:
            deadline = max(deadline, now + rpi_s)
        if now < deadline:
            return deadline
        self._counters.watchdog_timeouts += 1
        self._close(conn, f"watchdog: no O→T for {timeout_s * 1e3:.0f} ms (0x0203)")
        return None


__all__ = ["O2TWatchdogs"]

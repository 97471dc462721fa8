"""Layer: scanner (asyncio timers). Imports ``cobot_hmi.enip`` and the runtime support
(``udp_endpoint``).

The originator's O→T packets (issue 3: "send O→T from the same socket at the RPI with the run/idle
header"), sent by the cyclic pump as a periodic stream: one packet per RPI on a drift-free
schedule (``due += RPI``, never ``sleep(RPI)``), both sequence numbers raised by one per packet
by the pump itself (docs/protocol.md "Cyclic packets"), so we never wake to send. When the data
changes (a write, run/idle), :meth:`rebuild` hands the pump the new packet: the next one on the
wire carries it, with the next sequence numbers.

A fallback timer, pushed back every time T→O wakes us (``t2o_read``), fires only when T→O stops:
that is when the watchdog looks (``on_timer``). It is pushed back lazily: ``t2o_read`` only
notes the time, and the timer, when it comes, moves itself on to the fallback's due time from
that last read. A busy port wakes hundreds of times a second for its connections; cancelling and
making a loop timer per connection per wake-up cost more than the packets' decoding. Given the
connection's watchdog timeout (``watchdog_s``), the fallback is due exactly one timeout after
the last read: a steady stream then moves its timer on once per timeout (at RPI 10 ms, × 16:
every 160 ms) instead of every few wake-ups, and the timer that finds T→O silent fires when the
watchdog's verdict is due, not up to a fallback period after it. A timer that fired late (our
own loop stalled) looks again a wake-up period later, once the loop has read its sockets.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable

from cobot_hmi.enip import io
from cobot_hmi.udp_endpoint import BATCH_PERIOD_S, UdpEndpoint

PacketBuilder = Callable[[], bytes]
"""The datagram as it stands now (the pump writes both sequence numbers into each packet it
sends, whatever the template carries there)."""


def on_rpi_grid(now: float, rpi_s: float) -> float:
    """The first instant at or after ``now`` (loop time, ``time.monotonic``) that is a whole
    number of RPIs since the clock's origin.

    Every stream of one RPI starts on this grid, so the pump sends the O→T packets of all
    connections with that RPI in one wake-up per RPI (a PLC's I/O scan does the same), not one
    wake-up per connection at scattered phases: 16 robots at RPI 10 ms cost the pump 100
    wake-ups a second instead of 1600. RPIs that divide one another share ticks too (every
    fifth 2 ms tick is a 10 ms one). The first packet leaves at most one RPI after the Forward
    Open, well within the target's watchdog (RPI × (4 << multiplier), CIP Vol 1 §3-5.4.1). Counted
    in whole nanoseconds, the pump's unit, so that two streams' ticks are the same instant."""
    period_ns = max(1, round(rpi_s * 1e9))
    now_ns = round(now * 1e9)
    return -(-now_ns // period_ns) * period_ns / 1e9


class O2TStream:
    """One connection's O→T packets, a periodic stream of the pump of ``udp``."""

    def __init__(
        self,
        udp: UdpEndpoint,
        tag: int,
        addr: tuple[str, int],
        rpi_s: float,
        build: PacketBuilder,
        *,
        has_cip_seq: bool = True,
        wake_period_s: float = BATCH_PERIOD_S,
        on_timer: Callable[[float, float], None] | None = None,
        watchdog_s: float = 0.0,
    ) -> None:
        """``tag``: the stream's name in the pump, unique on ``udp`` (the connection ID when
        the socket serves one connection; an ``IoPort`` hands out its own, since two targets
        may choose the same O→T connection ID). ``has_cip_seq``: the packets carry a CIP
        sequence count (not a zero-size heartbeat).
        ``wake_period_s``: how often T→O wakes us at most. ``on_timer(now, lag_s)``: at each
        fallback wake-up, with how late the timer fired (the watchdog's cue: the timer only
        fires when T→O stopped coming, and a late timer means our own loop stalled).
        ``watchdog_s``: the connection's timeout, if it has one: the fallback waits that long
        after the last read (never less than a wake-up period and an RPI)."""
        self.rpi_s = rpi_s
        self.wake_period_s = max(rpi_s, wake_period_s)
        self._udp = udp
        self._tag = tag
        self._addr = addr
        self._build = build
        self._has_cip_seq = has_cip_seq
        self._on_timer = on_timer
        self._loop = asyncio.get_running_loop()
        self._timer: asyncio.TimerHandle | None = None
        self._timer_due = 0.0
        self._last_read = 0.0
        """Loop time T→O was last read (the fallback is due ``_fallback_s`` after it)."""
        self._fallback_s = max(1.5 * self.wake_period_s + rpi_s, watchdog_s)
        self._active = False
        self._sent_at_stop = 0
        self.timer_wakeups = 0

    @property
    def running(self) -> bool:
        return self._active

    def start(self) -> None:
        """The first packet at the next tick of the RPI's grid (sequence numbers 1), then one
        per RPI (see ``on_rpi_grid``)."""
        self._active = True
        now = self._loop.time()
        self._udp.send_every(
            self._tag,
            on_rpi_grid(now, self.rpi_s),
            self.rpi_s,
            self._build(),
            self._addr,
            (io.ENCAP_SEQ_OFFSET, 1),
            (io.CIP_SEQ_OFFSET, 1) if self._has_cip_seq else None,
        )
        self._arm(now)

    @property
    def sent(self) -> int:
        """Packets this stream has sent (the pump's own count: its encapsulation sequence
        number started at 1)."""
        if not self._active:
            return self._sent_at_stop
        following = self._udp.periodic_next(self._tag)
        return following[0] - 1 if following is not None else 0

    def stop(self) -> int:
        """Nothing more leaves; how many packets the stream sent."""
        if self._active:
            following = self._udp.stop_periodic(self._tag)
            self._sent_at_stop = following[0] - 1 if following is not None else 0
        self._active = False
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        return self._sent_at_stop

    def t2o_read(self, now: float | None = None) -> None:
        """T→O data was just read (at loop time ``now``, default the loop's clock): push the
        fallback timer back (lazily, see the module docstring)."""
        if self._active:
            self._last_read = self._loop.time() if now is None else now
            if self._timer is None:
                self._arm(self._last_read)

    def rebuild(self) -> None:
        """The data changed: the next packet carries the new data."""
        if self._active:
            self._udp.replace_periodic(self._tag, self._build())

    def _arm(self, now: float) -> None:
        self._last_read = now
        self._schedule(now + self._fallback_s)

    def _schedule(self, due: float) -> None:
        if self._timer is not None:
            self._timer.cancel()
        self._timer_due = due
        self._timer = self._loop.call_at(due, self._fire)

    def _fire(self) -> None:
        self._timer = None
        now = self._loop.time()
        due = self._last_read + self._fallback_s
        if due > now:  # T→O was read after the timer was set: the fallback moves on
            self._schedule(due)
            return
        self.timer_wakeups += 1
        lag_s = now - self._timer_due
        if self._on_timer is not None:
            self._on_timer(now, lag_s)
            if not self._active:
                return
        if lag_s > self.rpi_s:  # our loop stalled: look again soon, after it has read T→O
            self._schedule(now + self.wake_period_s)
        else:
            self._arm(now)


__all__ = ["O2TStream", "PacketBuilder"]

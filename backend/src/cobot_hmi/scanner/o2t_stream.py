"""Layer: scanner (asyncio timers). Imports only the runtime support (``udp_endpoint``).

The originator's O→T packets (issue 3: "send O→T from the same socket at the RPI with the run/idle
header"), built ahead and handed to the cyclic pump, which sends each at its due time.

The schedule is drift-free: packet k is due at ``start + k × RPI`` (``due += RPI``, never
``sleep(RPI)``). We do not wake per packet (a wake-up costs far more CPU than the packet: see
``udp_endpoint``): the packets of the next couple of wake periods wait in the pump, and each
wake-up tops the queue up. Wake-ups come with the T→O data (``t2o_read``, after the endpoint
read a batch), or from a fallback timer when T→O stops, which is also when the watchdog looks.

When the data changes (a write, run/idle), :meth:`rebuild` takes back every packet not sent yet
and builds them again, with the same sequence numbers: the next packet on the wire carries the
change, as if it had been built at its due time.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable

from cobot_hmi.udp_endpoint import BATCH_PERIOD_S, UdpEndpoint

PacketBuilder = Callable[[int, int], bytes]
"""``(encapsulation sequence number, CIP sequence count)`` → the datagram."""


class O2TStream:
    """One connection's O→T packets in the pump of ``udp``, under the connection ID as tag."""

    def __init__(
        self,
        udp: UdpEndpoint,
        connection_id: int,
        addr: tuple[str, int],
        rpi_s: float,
        build: PacketBuilder,
        *,
        wake_period_s: float = BATCH_PERIOD_S,
        on_timer: Callable[[float, float], None] | None = None,
    ) -> None:
        """``wake_period_s``: how often T→O wakes us at most (the queue covers it, at least one
        RPI). ``on_timer(now, lag_s)``: at each fallback wake-up, before topping up, with how
        late the timer fired (the watchdog's cue: the timer only fires when T→O stopped coming,
        and a late timer means our own loop stalled)."""
        self.rpi_s = rpi_s
        self.wake_period_s = max(rpi_s, wake_period_s)
        self._udp = udp
        self._tag = connection_id
        self._addr = addr
        self._build = build
        self._on_timer = on_timer
        self._loop = asyncio.get_running_loop()
        self._last_due = 0.0
        self._timer: asyncio.TimerHandle | None = None
        self._timer_due = 0.0
        self._active = False
        self.encap_seq = 0
        self.cip_seq = 0
        self.timer_wakeups = 0

    @property
    def running(self) -> bool:
        return self._active

    def start(self) -> None:
        """The first packet now, then one per RPI."""
        self._active = True
        now = self._loop.time()
        self._last_due = now - self.rpi_s
        self._top_up(now)
        self._arm(now)

    def stop(self) -> None:
        """Nothing more leaves: the timer stops and the queued packets are taken back."""
        self._active = False
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        self._udp.cancel(self._tag)

    def t2o_read(self) -> None:
        """T→O data was just read: top the queue up and push the fallback timer back."""
        if not self._active:
            return
        now = self._loop.time()
        self._top_up(now)
        self._arm(now)

    def rebuild(self) -> None:
        """The data changed: build every packet not sent yet again, from the first of them."""
        if not self._active:
            return
        count, first_due = self._udp.cancel(self._tag)
        if count and first_due is not None:
            self.encap_seq = (self.encap_seq - count) & 0xFFFFFFFF
            self.cip_seq = (self.cip_seq - count) & 0xFFFF
            self._last_due = first_due - self.rpi_s
        self._top_up(self._loop.time())

    def _top_up(self, now: float) -> None:
        # Up to the fallback timer and one more wake period: the queue never runs dry while
        # T→O flows, nor before the timer would top it up.
        horizon = now + 2.5 * self.wake_period_s + self.rpi_s
        due = self._last_due + self.rpi_s
        if due < now - self.rpi_s:
            due = now  # far behind (a stalled loop): resynchronise, never burst
        udp, build, addr, tag = self._udp, self._build, self._addr, self._tag
        while due <= horizon:
            self.encap_seq = (self.encap_seq + 1) & 0xFFFFFFFF
            self.cip_seq = (self.cip_seq + 1) & 0xFFFF
            udp.send_at(due, build(self.encap_seq, self.cip_seq), addr, tag)
            self._last_due = due
            due += self.rpi_s

    def _arm(self, now: float) -> None:
        due = now + 1.5 * self.wake_period_s + self.rpi_s
        if self._timer is not None:
            self._timer.cancel()
        self._timer_due = due
        self._timer = self._loop.call_at(due, self._fire)

    def _fire(self) -> None:
        self._timer = None
        self.timer_wakeups += 1
        now = self._loop.time()
        if self._on_timer is not None:
            self._on_timer(now, now - self._timer_due)
            if not self._active:
                return
        self._top_up(now)
        self._arm(now)


__all__ = ["O2TStream", "PacketBuilder"]

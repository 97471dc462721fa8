"""Layer: scanner (asyncio timers, no sockets). Imports nothing of the project.

When the originator's O→T packets leave (issue 3: "send O→T from the same socket at the RPI").

The schedule is drift-free: slot k ends at ``deadline = start + k × RPI`` (``deadline += RPI``,
never ``sleep(RPI)``), and every slot sends exactly one packet, so O→T runs at the RPI on average
whatever happens to T→O. A timer at the slot's deadline sends it when nothing else has.

Every wake-up of the process costs far more than the packet itself (a context switch and cold
caches: tens of microseconds of CPU, against a few for encoding and sending). When both
directions have the same RPI, the T→O packet that just arrived usually wakes us less than an RPI
from the deadline anyway, so the slot's packet goes out from that wake-up instead (``t2o_arrived``)
when the deadline is at most ``window`` away, and the timer, re-armed for the next slot, never
fires: one wake-up per cycle instead of two. A small phase-locked loop keeps T→O arrivals about
``window / 2`` ahead of the deadlines (each arrival moves the schedule by an eighth of its phase
error, at most RPI / 16 per slot), so arrival jitter of up to ± window / 2 still finds the
window, and a target whose clock runs slightly apart is followed instead of drifting out of it.
The timer stays the fallback: when T→O is late, early by more than the window or absent, the
slot's packet leaves at its deadline as before, and the watchdog sees the silence.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from typing import Final

WINDOW_SHARE: Final = 0.5
"""How long before its deadline a slot's packet may leave with a T→O arrival, in RPIs."""
PLL_GAIN: Final = 0.125
"""Share of the phase error corrected at each T→O arrival."""
PLL_MAX_STEP_SHARE: Final = 1 / 16
"""The largest correction per arrival, in RPIs (so one interval never changes by more)."""


class O2TSchedule:
    """One connection's O→T slots; ``send`` puts one packet on the wire."""

    def __init__(
        self,
        period_s: float,
        send: Callable[[], None],
        *,
        follow_t2o: bool,
        on_timer: Callable[[float, float], None] | None = None,
    ) -> None:
        """``follow_t2o``: send with T→O arrivals (only when both directions share the RPI).
        ``on_timer(now, lag_s)``: called at each timer wake-up before the packet, with how late
        the timer fired (the watchdog's cue: the timer only fires when T→O is not arriving in
        time, and a late timer means our own loop stalled)."""
        self.period_s = period_s
        self.window_s = period_s * WINDOW_SHARE
        self.follow_t2o = follow_t2o
        self._send = send
        self._on_timer = on_timer
        self._loop = asyncio.get_running_loop()
        self._deadline = 0.0
        self._timer: asyncio.TimerHandle | None = None
        self._active = False
        self.sent_with_t2o = 0
        self.sent_by_timer = 0

    @property
    def running(self) -> bool:
        return self._active

    def start(self) -> None:
        """The first packet now, then one per slot."""
        self._active = True
        now = self._loop.time()
        self._deadline = now
        self._send()
        self.sent_by_timer += 1
        self._arm(now + self.period_s)

    def stop(self) -> None:
        self._active = False
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None

    def t2o_arrived(self, now: float) -> None:
        """A new T→O frame was accepted at loop time ``now``."""
        if not self.follow_t2o or not self._active:
            return
        period = self.period_s
        lead = self._deadline - now
        error = lead - self.window_s / 2
        if error > period / 2:  # the phase is circular: this arrival is late for the last slot
            error -= period
        step = max(-period * PLL_MAX_STEP_SHARE, min(period * PLL_MAX_STEP_SHARE, error * PLL_GAIN))
        if lead <= self.window_s:
            self._send()
            self.sent_with_t2o += 1
            self._arm(self._deadline + period - step)
        elif step:
            self._arm(self._deadline - step)

    def _arm(self, deadline: float) -> None:
        now = self._loop.time()
        if deadline < now - self.period_s:
            deadline = now  # the loop stalled: resynchronise rather than burst
        self._deadline = deadline
        if self._timer is not None:
            self._timer.cancel()
        self._timer = self._loop.call_at(deadline, self._fire)

    def _fire(self) -> None:
        self._timer = None
        if self._on_timer is not None:
            now = self._loop.time()
            self._on_timer(now, now - self._deadline)
            if not self._active:
                return
        self._send()
        self.sent_by_timer += 1
        self._arm(self._deadline + self.period_s)


__all__ = ["O2TSchedule"]

"""Layer: service. One robot's connection as the service watches it: each state change and
slowness of the robot's T→O said as a connection event, the counters /metrics and the doors read
(times connected, times lost, down since), the connection alarms (lost, refused, stale, packet
loss) at each change and on the alarms' slow tick, and whether the robot is ready (/readyz).

Given what it reads and no more: the robot's link (its state, reason and gap count), its frames
(the newest one's age), its alarm engine, where events go, and what the robot does when the
connection comes up (``on_connected``: its identity read) or goes down (``on_down``: the receive
intervals' baseline reset, control dropped). Everything here runs on the web loop.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Callable
from typing import Protocol

from cobot_hmi.scanner.originator import ConnectionState
from cobot_hmi.scanner.t2o_pace import SlowTarget
from cobot_hmi.service.alarms.engine import TICK_S, AlarmEngine
from cobot_hmi.service.events.text import Event
from cobot_hmi.service.robots.frame_notifier import FrameNotifier

log = logging.getLogger(__name__)


class WatchedLink(Protocol):
    """What the watch reads of a robot's link (``robots.link.RobotLink``)."""

    @property
    def state(self) -> ConnectionState: ...

    @property
    def reason(self) -> str | None: ...

    @property
    def gaps(self) -> int: ...


class ConnectionWatch:
    """One robot's connection: its events, counters and connection alarms."""

    def __init__(
        self,
        name: str,
        link: WatchedLink,
        frames: FrameNotifier,
        alarms: AlarmEngine,
        *,
        publish_event: Callable[[Event], None],
        publish_events: Callable[[list[Event]], None],
        stale_after_s: float,
        on_connected: Callable[[], None],
        on_down: Callable[[ConnectionState], None],
    ) -> None:
        self.name = name
        self._link = link
        self._frames = frames
        self._alarms = alarms
        self._publish_event = publish_event
        self._publish_events = publish_events
        self._stale_after_s = stale_after_s
        self._on_connected = on_connected
        self._on_down = on_down
        self.connects = 0
        """Times the connection came up."""
        self.losses = 0
        """Times it went from connected to lost."""
        self.down_since: float | None = time.monotonic()
        """``time.monotonic()`` since the robot is not connected (``None``: connected)."""
        self._slow_target: SlowTarget | None = None
        """The last slowness of T→O reported (for the words once it clears)."""

    # ------------------------------------------------------------ the link's reports

    def on_state(self, state: ConnectionState, reason: str | None) -> None:
        """On the web loop: a connection state change of this robot only."""
        self._publish_event(
            {"kind": "connection", "time": time.time(), "state": state.value, "reason": reason}
        )
        for event in self.connection_alarms(time.time(), time.monotonic()):
            self._publish_event(event)
        if state is ConnectionState.CONNECTED:
            self.connects += 1
            self.down_since = None
            self._on_connected()
            return
        if self.down_since is None:
            self.down_since = time.monotonic()
            if state is ConnectionState.LOST:
                self.losses += 1
        self._on_down(state)

    def on_slow_target(self, slow: SlowTarget | None) -> None:
        """On the web loop: the robot sends T→O slower than it granted, or keeps its grant
        again (``scanner.t2o_pace``): a connection event in words, once each."""
        if slow is not None:
            self._slow_target = slow
            reason = slow.words("robot")
        elif self._slow_target is not None:
            reason = self._slow_target.kept_words("robot")
        else:
            return
        self._publish_event(
            {"kind": "connection", "time": time.time(), "state": "connected", "reason": reason}
        )

    # ------------------------------------------------------------ alarms (slow part)

    def connection_alarms(self, now_s: float, monotonic_s: float) -> list[Event]:
        """The connection alarms' events of the link as it is now."""
        state = self._link.state
        latest = self._frames.latest
        return self._alarms.connection(
            connected=state is ConnectionState.CONNECTED,
            refused=state is ConnectionState.REFUSED,
            reason=self._link.reason,
            frame_age_s=None if latest is None else max(0.0, now_s - latest.received_at_s),
            stale_after_s=self._stale_after_s,
            now_s=now_s,
            monotonic_s=monotonic_s,
        )

    async def alarm_loop(self) -> None:
        """The alarms' slow tick, until cancelled."""
        while True:
            await asyncio.sleep(TICK_S)
            try:
                self.alarm_tick()
            except Exception:  # a bug here must not end the alarms' tick
                log.exception("%s: alarm tick failed", self.name)

    def alarm_tick(self) -> None:
        """Connection, packet loss and shelving expiry, evaluated once."""
        now_s, monotonic_s = time.time(), time.monotonic()
        events = self.connection_alarms(now_s, monotonic_s)
        gaps = self._link.gaps if self._link.state is ConnectionState.CONNECTED else None
        events += self._alarms.gaps(gaps, now_s=now_s, monotonic_s=monotonic_s)
        events += self._alarms.expire_shelving(now_s)
        self._publish_events(events)

    # ------------------------------------------------------------ answers

    def down_for_s(self) -> float | None:
        """How long the robot has not been connected (``None``: connected)."""
        since = self.down_since
        return None if since is None else time.monotonic() - since

    def ready(self) -> tuple[bool, str | None]:
        """Connected (and frames coming), or why not: ``/readyz``."""
        state = self._link.state
        if state is not ConnectionState.CONNECTED:
            reason = self._link.reason
            return False, f"{state.value}{': ' + reason if reason else ''}"
        return True, None

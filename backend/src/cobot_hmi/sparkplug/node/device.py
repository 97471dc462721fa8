"""Layer: service (Sparkplug). One robot as a Sparkplug device: a consumer of its frames
(``robots.frame_notifier``) and what was last reported of it.
"""

from __future__ import annotations

import asyncio
import math
import time
from collections import Counter, deque
from collections.abc import Sequence
from typing import TYPE_CHECKING, Final

from cobot_hmi.codec import CommandImage, Frame
from cobot_hmi.service.robots.frame_notifier import FrameRecord, Runs
from cobot_hmi.sparkplug.catalogue import ALIAS_STRIDE, Catalogue, MetricDef
from cobot_hmi.sparkplug.event_metrics import (
    AlarmDeclaration,
    EventChange,
    EventMetrics,
)
from cobot_hmi.sparkplug.rbe import Reporter

if TYPE_CHECKING:
    from cobot_hmi.service.robots.robot import RobotRuntime


QUEUE_FRAMES: Final = 4096
"""Frames a robot's queue holds between two ticks (~40 s at RPI 10 ms)."""


def now_ms() -> int:
    return int(time.time() * 1000)


class Device:
    """One robot as a Sparkplug device: its frames, reporter and what was last reported.

    A consumer of the robot's frames (``robots.frame_notifier``) on the web loop: ``on_frames``
    keeps them (bounded: the oldest dropped and counted) and wakes the device's loop, which reports
    at most every ``period_s``, right after frames arrived."""

    name: Final = "sparkplug"
    runs: Final = Runs.LOOP
    queue_frames: Final = QUEUE_FRAMES

    def __init__(
        self,
        robot: RobotRuntime,
        number: int,
        catalogue: Catalogue,
        alarms: Sequence[AlarmDeclaration] = (),
    ) -> None:
        self.robot = robot
        self.catalogue = catalogue
        self.device_name = robot.name
        self.alias_base = number * ALIAS_STRIDE
        self.pending: deque[FrameRecord] = deque(maxlen=QUEUE_FRAMES)
        """Frames since the last report."""
        self.pending_dropped = 0
        self.arrived = asyncio.Event()
        self.registration = robot.frames.add(self)
        self.reporter = Reporter(catalogue)
        self.alive = False
        """Reported since its connection came up (a DBIRTH was made, sent or not)."""
        self.born = False
        """A DBIRTH went out in the current MQTT session."""
        self.connects_seen = -1
        self.frame: tuple[Frame, float] | None = None
        """The newest frame seen, and its receive time."""
        self.command: CommandImage | None = None
        self.holder = ""
        self.outcome: tuple[str, str] = ("", "")
        self.outcome_pending = False
        self.reported_at = -math.inf
        """``loop.time()`` of the last DDATA (published or buffered): the next one waits for
        ``period_s`` after it (the maximum rate)."""
        self.messages: Counter[str] = Counter()
        self.bytes: Counter[str] = Counter()
        self.events = self.event_metrics(alarms)
        """Its alarms, cycle times and health (``event_metrics``), after the catalogue's."""
        self.event_changes: list[EventChange] = []
        """Event metrics changed since the last report."""
        self.history_from_ms: int | None = None
        """Set when the robot's DDEATH went out: its next DBIRTH is followed by the alarm
        transitions since, as historical (they happened while it was offline)."""

    def event_metrics(self, alarms: Sequence[AlarmDeclaration]) -> EventMetrics:
        """Its event metrics with the alarms ``alarms`` (their state as declared)."""
        events = EventMetrics(len(self.catalogue.metrics), alarms, now_ms())
        if len(self.catalogue.metrics) + len(events.metrics) >= ALIAS_STRIDE:
            raise ValueError(f"{self.device_name}: too many alarms for its Sparkplug aliases")
        return events

    def metric(self, offset: int) -> MetricDef:
        """The metric at ``offset``: the catalogue's, then the event metrics."""
        metrics = self.catalogue.metrics
        return metrics[offset] if offset < len(metrics) else self.events.metric(offset)

    def on_event(self, event: dict[str, object]) -> None:
        """One event of the robot (on the web loop): what it changes, for the next report."""
        changes = self.events.on_event(event)
        if changes:
            self.event_changes.extend(changes)
            self.arrived.set()

    def take_event_changes(self) -> list[EventChange]:
        changes, self.event_changes = self.event_changes, []
        return changes

    def on_frames(self, robot: str, records: Sequence[FrameRecord]) -> None:
        pending = self.pending
        overflow = len(pending) + len(records) - QUEUE_FRAMES
        if overflow > 0:
            self.pending_dropped += overflow
        pending.extend(records)
        self.arrived.set()

    def take(self) -> list[FrameRecord]:
        """The frames since the last report, oldest first."""
        items = list(self.pending)
        self.pending.clear()
        return items

    @property
    def dropped(self) -> int:
        """Frames lost before a report saw them (the notifier's queue and ``pending``)."""
        return self.registration.dropped + self.pending_dropped

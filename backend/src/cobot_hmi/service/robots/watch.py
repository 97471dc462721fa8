"""Layer: service. Events seen in one robot's frames: state and flag changes, and its alarms.

A frame consumer (``robots.frame_notifier``) on the web loop: every frame in order goes through the
state and flag watcher (``events.text.FrameWatcher``) and the robot's alarm engine
(``service.alarms``: nothing allocated unless an alarm changes; the same ``Frame`` object
again, which the originator hands on while the robot's bytes do not change, is looked at by
the alarms only while a delay runs); the events they find are
published on the event bus (``events.bus``). Registered after the WebSocket fan-out, so a
client receives the frames before the events they caused.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Final, Protocol

from cobot_hmi.codec import Frame
from cobot_hmi.service.events.text import Event, FrameWatcher
from cobot_hmi.service.robots.frame_notifier import FrameRecord, Runs

QUEUE_FRAMES: Final = 4096
"""Frames the loop may fall behind by before the oldest are lost (~40 s at 10 ms)."""


class FrameAlarms(Protocol):
    """The robot's alarm engine (``service.alarms.engine.AlarmEngine``) as seen from here."""

    def observe(self, frame: Frame, time_s: float) -> list[Event] | None: ...


class FrameEventWatch:
    """State, flag and alarm events of one robot's frames (see the module docstring)."""

    name: Final = "events"
    runs: Final = Runs.LOOP
    queue_frames: Final = QUEUE_FRAMES

    def __init__(self, alarms: FrameAlarms, publish: Callable[[list[Event]], None]) -> None:
        self._watcher = FrameWatcher()
        self._alarms = alarms
        self._publish = publish
        self._last_frame: Frame | None = None

    def on_frames(self, robot: str, records: Sequence[FrameRecord]) -> None:
        events: list[Event] = []
        observe_alarms = self._alarms.observe
        for record in records:
            frame = record.frame
            if frame is not self._last_frame:
                # The same Frame again (unchanged bytes) changes no state or flag.
                self._last_frame = frame
                events.extend(self._watcher.observe(frame, record.received_at_s))
            alarm_events = observe_alarms(frame, record.received_at_s)
            if alarm_events:
                events.extend(alarm_events)
        if events:
            self._publish(events)

"""Layer: service (pure). One robot's cycles measured from its frames.

A cycle runs from one start (the trigger's level rising, ``trigger.CycleTrigger``) to the next;
both times are the receive times of the frames that showed the edge, so a cycle's duration is
exact to one frame (the RPI), never to a polling period. The first start after the service
starts, or after the frames stopped for longer than ``max_gap_s`` (a lost connection), only
opens a cycle: what happened in the silence is not known, so no cycle spans it.

``observe`` does no allocation unless a cycle ends: it runs for every frame of the robot.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

from cobot_hmi.codec import Frame
from cobot_hmi.service.cycles.trigger import CycleTrigger

MAX_GAP_S: Final = 1.0
"""Frames further apart than this break the cycle in progress (no cycle spans a silence)."""


@dataclass(frozen=True, slots=True)
class Cycle:
    robot: str
    start: float
    """Epoch seconds: the receive time of the frame that started it."""
    end: float
    """The receive time of the frame that started the next one."""

    @property
    def duration_s(self) -> float:
        return self.end - self.start


class CycleMeter:
    """Watches one robot's frames for its trigger (see the module docstring)."""

    __slots__ = ("_level", "_previous_s", "_start_s", "max_gap_s", "robot", "trigger")

    def __init__(self, robot: str, trigger: CycleTrigger, max_gap_s: float = MAX_GAP_S) -> None:
        self.robot = robot
        self.trigger = trigger
        self.max_gap_s = max_gap_s
        self._level: bool | None = None
        """The trigger's level in the last frame (``None``: no frame yet, or after a gap)."""
        self._previous_s: float | None = None
        self._start_s: float | None = None
        """When the cycle in progress started."""

    @property
    def started_at(self) -> float | None:
        """When the cycle in progress started (``None``: none is)."""
        return self._start_s

    def observe(self, frame: Frame, time_s: float) -> Cycle | None:
        """The cycle this frame ended (its start edge began the next one), or ``None``."""
        previous = self._previous_s
        self._previous_s = time_s
        if previous is not None and time_s - previous > self.max_gap_s:
            self._level = None
            self._start_s = None
        level = self.trigger.level(frame)
        was = self._level
        self._level = level
        if not level or was is None or was:
            return None  # no rising edge (the first frame only says where the level is)
        start, self._start_s = self._start_s, time_s
        if start is None:
            return None
        return Cycle(self.robot, start, time_s)

"""Layer: service (pure). One robot's cycles measured from its frames.

A cycle runs from one start (the trigger's level rising, ``robots.cycle_trigger.CycleTrigger``)
to the next; both times are the receive times of the frames that showed the edge, so a cycle's
duration is exact to one frame (the RPI), never to a polling period. The first start after the
service starts only opens a cycle.

A cycle in which the robot stopped (an emergency or safety stop, a protective stop, safe off),
its frames stopped for longer than ``max_gap_s`` (a lost link), or it left its running states
(running at the start, standby, manual or recovery later) is **interrupted**: it is measured
and kept with what interrupted it (``Cycle.interruption``), so it is shown apart and left out
of the statistics, rather than a 142 s "cycle" across two e-stops among 8 s ones. (A trigger
on a state, ``state:STANDALONE_RUNNING``, leaves the running state every cycle: for it only a
stop or a lost link interrupts.)

``observe`` does no allocation unless a cycle ends or is interrupted: it runs for every frame
of the robot.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

from cobot_hmi.codec import Frame
from cobot_hmi.layout import ROBOT_STATES
from cobot_hmi.service.robots.cycle_trigger import CycleTrigger

MAX_GAP_S: Final = 1.0
"""Frames further apart than this interrupt the cycle in progress (a lost link)."""

_STATE: Final = {state.name: state.value for state in ROBOT_STATES}
_STATE_LABELS: Final = {state.value: state.label or state.name for state in ROBOT_STATES}
RUNNING_STATES: Final = frozenset(
    _STATE[name]
    for name in (
        "STANDALONE_RUNNING",
        "COLLABORATIVE_RUNNING",
        "HIGH_PRIORITY_RUNNING",
        "HANDGUIDING_CONTROL_STANDBY",  # a hand-guiding command of the running task program
        "HANDGUIDING_CONTROL_RUNNING",
    )
)
"""The states in which the task program runs (the layout's state table)."""
STOP_STATES: Final = frozenset(_STATE[n] for n in ("EMERGENCY_STOP", "SAFE_OFF", "INTERRUPTED"))
"""The robot stopped: emergency stop, safe off (servo off), protective stop."""


@dataclass(frozen=True, slots=True)
class Cycle:
    robot: str
    start: float
    """Epoch seconds: the receive time of the frame that started it."""
    end: float
    """The receive time of the frame that started the next one."""
    interruption: str | None = None
    """What interrupted it, in words ("Emergency stop", "no frames for 3.2 s"); ``None``: a
    whole cycle."""

    @property
    def interrupted(self) -> bool:
        return self.interruption is not None

    @property
    def duration_s(self) -> float:
        return self.end - self.start


class CycleMeter:
    """Watches one robot's frames for its trigger (see the module docstring)."""

    __slots__ = (
        "_interruption",
        "_level",
        "_previous_s",
        "_running_at_start",
        "_start_s",
        "max_gap_s",
        "robot",
        "trigger",
    )

    def __init__(self, robot: str, trigger: CycleTrigger, max_gap_s: float = MAX_GAP_S) -> None:
        self.robot = robot
        self.trigger = trigger
        self.max_gap_s = max_gap_s
        self._level: bool | None = None
        """The trigger's level in the last frame (``None``: no frame yet, or after a gap)."""
        self._previous_s: float | None = None
        self._start_s: float | None = None
        """When the cycle in progress started."""
        self._interruption: str | None = None
        """What interrupted the cycle in progress (``None``: nothing yet)."""
        self._running_at_start = False
        """Whether the robot was in a running state when the cycle in progress started."""

    @property
    def started_at(self) -> float | None:
        """When the cycle in progress started (``None``: none is)."""
        return self._start_s

    def observe(self, frame: Frame, time_s: float) -> Cycle | None:
        """The cycle this frame ended (its start edge began the next one), or ``None``."""
        previous = self._previous_s
        self._previous_s = time_s
        if previous is not None and time_s - previous > self.max_gap_s:
            self._level = None  # the first frame after the silence only says where it is
            if self._interruption is None:
                self._interruption = f"no frames for {time_s - previous:.1f} s (link lost)"
        if self._start_s is not None and self._interruption is None:
            self._interruption = self._stopped(frame)
        level = self.trigger.level(frame)
        was = self._level
        self._level = level
        if not level or was is None or was:
            return None  # no rising edge (the first frame only says where the level is)
        start, self._start_s = self._start_s, time_s
        interruption, self._interruption = self._interruption, None
        self._running_at_start = frame.robot_state in RUNNING_STATES
        if start is None:
            return None
        return Cycle(self.robot, start, time_s, interruption)

    def _stopped(self, frame: Frame) -> str | None:
        """What in ``frame`` interrupts the cycle in progress, in words, or ``None``."""
        state = frame.robot_state
        if frame.emergency_stopped:
            return "Emergency stop"
        if state in STOP_STATES:
            return _STATE_LABELS[state]
        if frame.safety_stopped:
            return "Safety stop"
        if self._running_at_start and state not in RUNNING_STATES and self.trigger.state is None:
            return f"left running: {_STATE_LABELS.get(state, f'state {state}')}"
        return None

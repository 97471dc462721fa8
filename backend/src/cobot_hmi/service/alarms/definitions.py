"""Layer: service. What an alarm is: its key, its words, its priority and colour; the built-in
alarms of every robot and the user's (``[[alarms]]`` in the settings file). Pure: imports the
layout, the labels and the settings' types.

Priorities (ISA-18.2 §10: a few, by the consequence and the time to respond) are critical,
high, medium and low, and below them advisory: robot health's maintenance advice
(``service.health``: a joint's verdict watch or act), never above any alarm that needs an
answer now. Their colours follow the teach pendant's semantics, taken from the
layout's robot-state colours where a state gives one: critical is the emergency stop's red,
medium the protective stop's yellow, low the informational blue of the manual states; high is
orange, between red and yellow, as ISA-101 displays use it (the pendant has no state for it).
An alarm that is a robot state shows that state's own pendant colour. Advisory is grey: a
planner's note, not a call to the cell.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from typing import Final, Literal

from cobot_hmi.layout import ROBOT_STATES, Direction, field_by_name
from cobot_hmi.service.labels import element_label, unit_of

PriorityName = Literal["critical", "high", "medium", "low", "advisory"]


class Priority(StrEnum):
    CRITICAL = "critical"
    HIGH = "high"
    MEDIUM = "medium"
    LOW = "low"
    ADVISORY = "advisory"
    """Robot health's maintenance advice (``service.health``): below every other priority."""

    @property
    def rank(self) -> int:
        """0 for critical … 3 for low, 4 for advisory: sorts the most urgent first."""
        return _RANK[self]

    @property
    def colour(self) -> str:
        return PRIORITY_COLOURS[self]


_RANK: Final = {
    Priority.CRITICAL: 0,
    Priority.HIGH: 1,
    Priority.MEDIUM: 2,
    Priority.LOW: 3,
    Priority.ADVISORY: 4,
}
_STATE_COLOUR: Final = {s.name: s.pendant_colours[0] for s in ROBOT_STATES}
PRIORITY_COLOURS: Final = {
    Priority.CRITICAL: _STATE_COLOUR["EMERGENCY_STOP"],
    Priority.HIGH: "orange",
    Priority.MEDIUM: _STATE_COLOUR["INTERRUPTED"],
    Priority.LOW: _STATE_COLOUR["MANUAL_STANDBY"],
    Priority.ADVISORY: "grey",
}

AlarmKind = Literal["state", "connection", "rate", "limit", "bit", "recording", "health"]


@dataclass(frozen=True, slots=True)
class AlarmDefinition:
    """One alarm of one robot (its state lives in ``state.AlarmStatus``)."""

    key: str
    """Unique per robot: ``emergency_stop``, ``motor_temperature.2``, ``user.gripper_low``."""
    name: str
    """In words: "Emergency stop", "Motor temperature J 3 high"."""
    priority: Priority
    kind: AlarmKind
    description: str
    colour: str
    element: str | None = None
    """The frame element it watches (``joint_motor_temperature.2``), for its label and tag."""
    high: float | None = None
    low: float | None = None
    unit: str = ""

    @property
    def label(self) -> str | None:
        """The spec's label of the watched element (``J 3``, ``DO 3``)."""
        return element_label(self.element) if self.element is not None else None


EMERGENCY_STOP: Final = "emergency_stop"
PROTECTIVE_STOP: Final = "protective_stop"
SAFE_OFF: Final = "safe_off"
CONNECTION_LOST: Final = "connection_lost"
FORWARD_OPEN_REFUSED: Final = "forward_open_refused"
PACKET_LOSS: Final = "packet_loss"
RECORDING_PAUSED: Final = "recording_paused"
MOTOR_TEMPERATURE: Final = "motor_temperature"
HEALTH: Final = "health"
"""``health.1`` … ``health.6``: each joint's maintenance advice (``service.health``)."""
USER_PREFIX: Final = "user."


def _state(key: str, name: str, state: str, priority: Priority) -> AlarmDefinition:
    info = next(s for s in ROBOT_STATES if s.name == state)
    return AlarmDefinition(
        key,
        name,
        priority,
        "state",
        f"{state} ({info.value}): {info.description}",
        _STATE_COLOUR[state],
    )


def builtin_definitions(
    *, motor_temperature_c: float, gap_rate_per_min: float
) -> tuple[AlarmDefinition, ...]:
    """Every robot's built-in alarms, most urgent first."""
    temperature = field_by_name(Direction.T_TO_O, "joint_motor_temperature")
    return (
        _state(EMERGENCY_STOP, "Emergency stop", "EMERGENCY_STOP", Priority.CRITICAL),
        _state(PROTECTIVE_STOP, "Protective stop", "INTERRUPTED", Priority.HIGH),
        _state(SAFE_OFF, "Servo off after an error (SAFE_OFF)", "SAFE_OFF", Priority.HIGH),
        AlarmDefinition(
            CONNECTION_LOST,
            "Connection lost or stale",
            Priority.HIGH,
            "connection",
            "the class 1 connection is down, or no frame came for longer than stale_after_ms",
            PRIORITY_COLOURS[Priority.HIGH],
        ),
        AlarmDefinition(
            FORWARD_OPEN_REFUSED,
            "Forward Open refused",
            Priority.HIGH,
            "connection",
            "the robot refused the class 1 connection (the reason names its CIP status)",
            PRIORITY_COLOURS[Priority.HIGH],
        ),
        AlarmDefinition(
            PACKET_LOSS,
            "Packet loss",
            Priority.MEDIUM,
            "rate",
            f"more than {gap_rate_per_min:g} T→O sequence gaps in a minute",
            PRIORITY_COLOURS[Priority.MEDIUM],
            high=gap_rate_per_min,
            unit="gaps/min",
        ),
        AlarmDefinition(
            RECORDING_PAUSED,
            "Recording paused: disk full",
            Priority.HIGH,
            "recording",
            "the history recorder cannot write (disk full, free space under "
            "history_min_free_bytes, or a write error): frames go unrecorded until it resumes",
            PRIORITY_COLOURS[Priority.HIGH],
        ),
        *(
            AlarmDefinition(
                f"{MOTOR_TEMPERATURE}.{index}",
                f"Motor temperature {channel} high",
                Priority.MEDIUM,
                "limit",
                f"joint {channel} motor temperature above {motor_temperature_c:g} °C",
                PRIORITY_COLOURS[Priority.MEDIUM],
                element=f"joint_motor_temperature.{index}",
                high=motor_temperature_c,
                unit=temperature.unit,
            )
            for index, channel in enumerate(temperature.channels)
        ),
        *(
            AlarmDefinition(
                f"{HEALTH}.{index + 1}",
                f"Maintenance advised: {channel}",
                Priority.ADVISORY,
                "health",
                f"robot health reads joint {channel} as watch or act (wear, heat, reducer life or "
                "knocks against its baseline): the message says why; it clears once the joint "
                "reads ok again",
                PRIORITY_COLOURS[Priority.ADVISORY],
            )
            for index, channel in enumerate(temperature.channels)
        ),
    )


def user_definition(
    name: str,
    element: str,
    *,
    priority: str,
    message: str,
    high: float | None,
    low: float | None,
    bit: bool,
    active_when: bool,
) -> AlarmDefinition:
    """The definition of a user alarm (``[[alarms]]``) on one element."""
    label = element_label(element) or element
    if bit:
        what = f"{label} is {'on' if active_when else 'off'}"
    else:
        unit = unit_of(element)
        limits = []
        if high is not None:
            limits.append(f"above {high:g} {unit}".rstrip())
        if low is not None:
            limits.append(f"below {low:g} {unit}".rstrip())
        what = f"{label} {' or '.join(limits)}"
    level = Priority(priority)
    return AlarmDefinition(
        f"{USER_PREFIX}{name}",
        message or what,
        level,
        "bit" if bit else "limit",
        what,
        level.colour,
        element=element,
        high=high,
        low=low,
        unit="" if bit else unit_of(element),
    )

"""Layer: service. Events seen in the frame stream: robot state transitions and flag changes.

Every field name and state name comes from the layout table. Pure: no I/O.
"""

from __future__ import annotations

from typing import Final

from cobot_hmi.codec import Frame
from cobot_hmi.layout import flag_fields, robot_state_name

Event = dict[str, object]
"""``{"kind": …, "time": t, …}`` as ``docs/api.md`` defines it."""

FLAG_NAMES: Final = tuple(f.name for f in flag_fields())
FLAG_LABELS: Final = {f.name: f.description for f in flag_fields()}
"""Each flag in words, as the layout describes it ("Servo on")."""


def robot_state_event(time_s: float, old: int | None, new: int) -> Event:
    return {
        "kind": "robot_state",
        "time": time_s,
        "from": old,
        "to": new,
        "from_name": None if old is None else robot_state_name(old),
        "to_name": robot_state_name(new),
    }


class FrameWatcher:
    """Remembers the last robot state and flags and reports what each new frame changes.

    The memory survives reconnections: a state or flag that changed while the connection was
    down is reported by the first frame after it, and the very first frame reports the state
    (``from`` null) so the event log always says where the robot started.
    """

    def __init__(self) -> None:
        self._state: int | None = None
        self._flags: tuple[bool, ...] | None = None

    def observe(self, frame: Frame, time_s: float) -> list[Event]:
        events: list[Event] = []
        state = frame.robot_state
        if state != self._state:
            events.append(robot_state_event(time_s, self._state, state))
            self._state = state
        flags = tuple(bool(getattr(frame, name)) for name in FLAG_NAMES)
        if flags != self._flags:
            if self._flags is not None:
                for name, old, new in zip(FLAG_NAMES, self._flags, flags, strict=True):
                    if old != new:
                        events.append(
                            {
                                "kind": "flag",
                                "time": time_s,
                                "flag": name,
                                "value": new,
                                "label": FLAG_LABELS[name],
                            }
                        )
            self._flags = flags
        return events

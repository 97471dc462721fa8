"""Layer: service. Events seen in the frame stream (robot state transitions and flag changes),
and every event in words (``event_text``).

Every field name and state name comes from the layout table; the words of states, flags and
elements from ``labels``. Pure: no I/O.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Final

from cobot_hmi.codec import Frame
from cobot_hmi.layout import flag_fields, robot_state_name
from cobot_hmi.service.labels import flag_words, labels_of, robot_state_words

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


# --------------------------------------------------------------------------- in words


def _text(value: object) -> str | None:
    return value if isinstance(value, str) and value else None


def _because(reason: object) -> str:
    words = _text(reason)
    return f" ({words})" if words else ""


def _robot_state_text(event: Mapping[str, object]) -> str:
    new, old = event.get("to"), event.get("from")
    now = robot_state_words(new if isinstance(new, int) else None)
    if not isinstance(old, int):
        return f"Robot state {now} (first frame)"
    return f"Robot state {now} (was {robot_state_words(old)})"


def _write_text(event: Mapping[str, object]) -> str:
    what = _text(event.get("summary"))
    if what is None:
        fields = event.get("fields")
        labels = labels_of(fields)
        names = fields if isinstance(fields, list) else []
        what = ", ".join(labels.get(str(f), str(f)) for f in names) or "nothing"
    user = _text(event.get("user")) or "someone without a login"
    return f"Write by {user}: {what} → {event.get('outcome')}{_because(event.get('reason'))}"


def _control_text(event: Mapping[str, object]) -> str:
    holder = event.get("holder")
    user = _text(holder.get("user")) if isinstance(holder, Mapping) else None
    held = f"Control held by {user}" if user else "Control free, nobody holds it"
    reason = _text(event.get("reason"))
    return f"{held}: {reason}" if reason else held


_TRANSITION_WORDS: Final = {
    "activated": "activated",
    "cleared": "returned to normal",
    "acknowledged": "acknowledged",
    "shelved": "shelved",
    "unshelved": "unshelved",
    "shelve_expired": "unshelved (shelving expired)",
}


def _alarm_text(event: Mapping[str, object]) -> str:
    alarm = event.get("alarm")
    alarm = alarm if isinstance(alarm, Mapping) else {}
    name = _text(alarm.get("name")) or str(alarm.get("id", "alarm"))
    transition = str(event.get("transition", ""))
    words = f"{name} {_TRANSITION_WORDS.get(transition, transition.replace('_', ' '))}"
    user = _text(event.get("user"))
    if user:
        words += f" by {user}"
    comment = _text(event.get("comment"))
    if comment:
        words += f" — {comment}"
    cause = _text(alarm.get("suppressed_by_name"))
    if transition == "activated" and alarm.get("state") == "suppressed" and cause:
        words += f", suppressed by design (a consequence of {cause})"
    message = _text(alarm.get("message"))
    if message and transition in ("activated", "cleared"):
        words += f": {message}"
    return words


def _session_text(event: Mapping[str, object]) -> str:
    count = event.get("streams_closed")
    streams = f"{count} stream{'' if count == 1 else 's'}"
    return f"Session of {event.get('user')} ended{_because(event.get('reason'))}: {streams} closed"


def _recording_text(event: Mapping[str, object]) -> str:
    """The recorder's reason says what happened ("the recorder fell behind: 12 frames not
    recorded", "recording resumed"); a pause is said as one."""
    state, reason = event.get("state"), _text(event.get("reason"))
    if state == "paused":
        return f"Recording paused: {reason}" if reason else "Recording paused"
    if reason:
        return f"Recording: {reason}"
    return "Recording fell behind" if state == "overflow" else "Recording resumed"


def _health_text(event: Mapping[str, object]) -> str:
    """The joints that need a look, with their reasons; or that every joint reads ok."""
    joints = event.get("joints")
    flagged = [
        j
        for j in (joints if isinstance(joints, list) else [])
        if isinstance(j, Mapping) and j.get("verdict") in ("watch", "act")
    ]
    if not flagged:
        return "Health: every joint ok"
    return "Health: " + "; ".join(f"{j.get('verdict')}: {j.get('reason')}" for j in flagged)


def event_text(event: Mapping[str, object]) -> str:
    """The event in words, one line, as every view and file shows it (``text``)."""
    kind = event.get("kind")
    if kind == "robot_state":
        return _robot_state_text(event)
    if kind == "flag":
        flag = str(event.get("flag", ""))
        return flag_words(flag, event.get("value") is True)
    if kind == "connection":
        reason = _text(event.get("reason"))
        return f"Connection {event.get('state')}{': ' + reason if reason else ''}"
    if kind == "write":
        return _write_text(event)
    if kind == "control":
        return _control_text(event)
    if kind == "alarm":
        return _alarm_text(event)
    if kind == "session":
        return _session_text(event)
    if kind == "recording":
        return _recording_text(event)
    if kind == "health":
        return _health_text(event)
    if kind == "cycle":
        duration_s = event.get("duration_s")
        if isinstance(duration_s, int | float):
            why = event.get("interruption")
            return f"Cycle of {duration_s:.2f} s" + (f", interrupted: {why}" if why else "")
        return "Cycle"
    return f"{kind} event"


def with_text(event: dict[str, object]) -> dict[str, object]:
    """``event`` with its ``text`` (an event logged before events had one gets it here)."""
    if not isinstance(event.get("text"), str):
        event["text"] = event_text(event)
    return event

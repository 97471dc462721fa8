"""Layer: service (pure). A robot's cycle trigger: what in its T→O frame starts a cycle.

Written as text in the settings (``cycle_trigger``):

- ``FIELD.INDEX:rising`` / ``FIELD.INDEX:falling``: an edge of one bit of an array field of the
  frame, keyed as everywhere in the API (``bit_output_registers.63``, ``controlbox_di.4`` is
  DI 5, ``controlbox_do.2`` is DO 3, ``tool_di.0``, ``tool_do.1``);
- ``FIELD:rising`` / ``FIELD:falling``: an edge of one of the five flags (``servo_on``);
- ``state:NAME``: the robot entering a state (``state:STANDALONE_RUNNING``; the names of the
  layout's state enum);
- empty: no cycle timing.

``parse_trigger`` checks the text against the layout and says what is wrong in words. Imports
only the layout and the codec's ``Frame``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

from cobot_hmi.codec import Frame
from cobot_hmi.layout import ROBOT_STATES, T2O_FIELDS, CipType, Field

EDGES: Final = ("rising", "falling")
_BIT_ARRAYS: Final = {
    f.name: f
    for f in T2O_FIELDS
    if f.cip_type is CipType.BOOL and not f.scalar and not f.value_names
}
_FLAGS: Final = {f.name: f for f in T2O_FIELDS if f.flag is not None}
_STATES: Final = {state.name: state for state in ROBOT_STATES}


class TriggerError(ValueError):
    """The trigger's text names nothing of the frame, or no edge; the message says what."""


@dataclass(frozen=True, slots=True)
class CycleTrigger:
    """One bit of the frame whose rising edge starts a cycle (``falling``: its falling edge;
    a state: the bit "the robot is in that state")."""

    text: str
    """As written in the settings."""
    field: str
    """``robot_state`` for a state trigger."""
    index: int | None
    """The bit's index in an array field; ``None`` for a flag or a state."""
    falling: bool = False
    state: int | None = None
    """The state's value for ``state:NAME``."""

    def level(self, frame: Frame) -> bool:
        """The trigger's bit in ``frame``, inverted for a falling edge (so a cycle starts on
        every rise of the level)."""
        if self.state is not None:
            return frame.robot_state == self.state
        value = getattr(frame, self.field)
        if self.index is not None:
            value = value[self.index]
        return bool(value) != self.falling

    @property
    def label(self) -> str:
        """In words, named as the robot prints it, for the panel: "rising edge of Register out
        63", "falling edge of DI 5", "rising edge of Servo on", "entering Standalone running"."""
        if self.state is not None:
            return f"entering {_STATE_LABELS.get(self.state, self.text.partition(':')[2])}"
        edge = "falling" if self.falling else "rising"
        return f"{edge} edge of {_element_label(self.field, self.index)}"


_REGISTERS: Final = {"bit_output_registers": "Register out"}
"""The layout labels both register banks "Register n"; the robot's own bank (T→O) is named by
its direction, as the I/O checkout names it ("Register out 63")."""
_STATE_LABELS: Final = {state.value: state.label or state.name for state in ROBOT_STATES}


def _element_label(name: str, index: int | None) -> str:
    field: Field | None = _BIT_ARRAYS.get(name) or _FLAGS.get(name)
    if field is None:
        return name if index is None else f"{name}.{index}"
    if index is None or not field.channels:
        return field.description if index is None else f"{name}.{index}"
    label = field.channels[index]
    prefix = _REGISTERS.get(name)
    return label.replace("Register", prefix, 1) if prefix else label


def _array_bit(name: str, index_text: str, edge: str, text: str) -> CycleTrigger:
    field: Field | None = _BIT_ARRAYS.get(name)
    if field is None:
        raise TriggerError(
            f"cycle trigger {text!r}: {name!r} is not a bit array of the frame; "
            f"one of {', '.join(_BIT_ARRAYS)}"
        )
    if not index_text.isdigit() or int(index_text) >= field.count:
        raise TriggerError(
            f"cycle trigger {text!r}: {name} has bits 0–{field.count - 1}, not {index_text!r}"
        )
    return CycleTrigger(text, name, int(index_text), falling=edge == "falling")


def parse_trigger(text: str) -> CycleTrigger | None:
    """The trigger ``text`` names (``None`` for an empty text); ``TriggerError`` otherwise."""
    text = text.strip()
    if not text:
        return None
    where, sep, what = text.partition(":")
    where, what = where.strip(), what.strip()
    if not sep:
        raise TriggerError(
            f"cycle trigger {text!r}: expected FIELD.INDEX:rising|falling, FLAG:rising|falling "
            "or state:NAME"
        )
    if where == "state":
        state = _STATES.get(what.upper())
        if state is None:
            raise TriggerError(
                f"cycle trigger {text!r}: no robot state {what!r}; one of {', '.join(_STATES)}"
            )
        return CycleTrigger(f"state:{state.name}", "robot_state", None, state=state.value)
    edge = what.lower()
    if edge not in EDGES:
        raise TriggerError(f"cycle trigger {text!r}: the edge is rising or falling, not {what!r}")
    name, dot, index_text = where.partition(".")
    if dot:
        return _array_bit(name, index_text, edge, text)
    if name not in _FLAGS:
        raise TriggerError(
            f"cycle trigger {text!r}: {name!r} is no flag; a bit of an array needs its index "
            f"(FIELD.INDEX); flags: {', '.join(_FLAGS)}"
        )
    return CycleTrigger(text, name, None, falling=edge == "falling")

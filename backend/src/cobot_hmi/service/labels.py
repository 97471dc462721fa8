"""Layer: service. The spec's own labels of the I/O elements and their values in words. Pure.

The API names an element ``field.index`` with a 0-based index into the frame's array
(``controlbox_do.2``); people read the label the robot prints (``DO 3``). Every place that
shows an element to a person (events, audit rows, alarms, tag names) takes the label from here,
and here only from ``cobot_hmi.layout`` (its ``channels``): ``controlbox_do.2`` is DO 3,
``tool_do.0`` is Tool DO 1, ``analog_output.0`` is AO 0, ``bit_input_registers.40`` is
Register 40. A coded field (the analog output type) is labelled after its channel with
"type" (``analog_output_type.1`` is "AO 1 type"), so a type and a value written together are
not both "AO 1". Robot states and flags are named in words too (``robot_state_words``,
``flag_words``): an event or an alarm never shows a bare state number. Imports only the layout.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Final

from cobot_hmi.layout import (
    ANALOG_OUTPUT_RANGES,
    O2T_FIELDS,
    ROBOT_STATES,
    T2O_FIELDS,
    Field,
)

_BY_NAME: Final[dict[str, Field]] = {}
for _field in (*T2O_FIELDS, *O2T_FIELDS):  # T→O first: the actual output's description
    _BY_NAME.setdefault(_field.name, _field)

_STATE_LABELS: Final = {s.value: s.label or s.name for s in ROBOT_STATES}
_ANALOG_TYPES: Final = ("current", "voltage")
_PER_TYPE_UNIT: Final = "mA or V per its type"


def split_key(key: str) -> tuple[str, int | None]:
    """``"controlbox_do.2"`` → ``("controlbox_do", 2)``; ``"servo_on"`` → ``("servo_on", None)``.
    ``ValueError`` when the index part is not a decimal."""
    name, dot, index = key.partition(".")
    if not dot:
        return name, None
    if not index.isdecimal() or (len(index) > 1 and index.startswith("0")):
        raise ValueError(f"{key!r}: the index after the dot must be a decimal without leading 0")
    return name, int(index)


def element_label(key: str) -> str | None:
    """The label of an element key as the robot prints it, or ``None`` for a key that names
    no element of the layout (an alarm's own key, a malformed body's key).

    ``controlbox_do.2`` → "DO 3"; ``analog_output_type.1`` → "AO 1 type";
    ``joint_motor_temperature.2`` → "J 3"; a scalar field (``servo_on``) → its description.
    """
    try:
        name, index = split_key(key)
    except ValueError:
        return None
    f = _BY_NAME.get(name)
    if f is None:
        return None
    if index is None:
        return f.description if (f.scalar or f.count == 1) else None
    if not 0 <= index < f.count:
        return None
    if f.channels:
        label = f.channels[index]
        return f"{label} type" if f.value_names else label
    if f.element_names:
        return f"{f.description}: {f.element_names[index]}"
    return f"{f.name}[{index}]"


def labels_of(keys: object) -> dict[str, str]:
    """``{key: label}`` for every key of ``keys`` (a list of ``field.index``) that has one."""
    out: dict[str, str] = {}
    if isinstance(keys, list | tuple):
        for key in keys:
            if isinstance(key, str):
                label = element_label(key)
                if label is not None:
                    out[key] = label
    return out


def unit_of(key: str, analog_type: int | None = None) -> str:
    """The unit of an element's value: the layout's, an analog value's by its type code
    (0 current: mA, 1 voltage: V; unknown: "mA or V")."""
    name, _ = split_key(key)
    f = _BY_NAME.get(name)
    if f is None:
        return ""
    if f.unit == _PER_TYPE_UNIT:
        if analog_type is not None and 0 <= analog_type < len(_ANALOG_TYPES):
            return ANALOG_OUTPUT_RANGES[_ANALOG_TYPES[analog_type]][2]
        return "mA or V"
    return f.unit


def value_words(key: str, value: object, analog_type: int | None = None) -> str:
    """An element's value as a person reads it: bits "on"/"off", a coded value by its name
    ("voltage"), a number with its unit ("5 V", "81.5 °C")."""
    try:
        name, _ = split_key(key)
    except ValueError:
        return str(value)
    f = _BY_NAME.get(name)
    if isinstance(value, bool):
        return "on" if value else "off"
    if f is not None and f.value_names and isinstance(value, int):
        return f.value_names[value] if 0 <= value < len(f.value_names) else str(value)
    if isinstance(value, int | float):
        if isinstance(value, float) and not math.isfinite(value):
            return "not a number"
        unit = unit_of(key, analog_type)
        return f"{value:g} {unit}".rstrip()
    return "null" if value is None else str(value)


def named(key: str, tags: Mapping[str, str] | None = None) -> str:
    """The label, with the tag name when there is one: "DO 3 (gripper close)"."""
    label = element_label(key) or key
    tag = tags.get(key) if tags else None
    return f"{label} ({tag})" if tag else label


def write_summary(
    values: Mapping[str, object],
    analog_types: tuple[int, ...] | None = None,
    tags: Mapping[str, str] | None = None,
) -> str:
    """What a write asked for, in words, in the given order:
    ``"AO 1 type = voltage, AO 1 = 5 V"``. ``analog_types``: the analog output types after the
    write (the unit of an analog value follows the type written with it)."""
    parts = []
    for key, value in values.items():
        analog_type = None
        name, index = split_key(key) if "." in key else (key, None)
        if name == "analog_output" and analog_types is not None and index is not None:
            analog_type = analog_types[index] if index < len(analog_types) else None
        parts.append(f"{named(key, tags)} = {value_words(key, value, analog_type)}")
    return ", ".join(parts)


def robot_state_words(value: int | None) -> str:
    """A robot state as people read it: the layout's label ("Safe off (servo off)"); a value
    outside the table as "state 42 (unknown)"; ``None`` as "unknown (no frame)"."""
    if value is None:
        return "unknown (no frame)"
    label = _STATE_LABELS.get(value)
    return label if label is not None else f"state {value} (unknown)"


def flag_words(name: str, value: bool) -> str:
    """A status flag's change in words: "Servo on flag set", "Emergency stopped flag cleared"
    (the flag's description is itself a state, so "on"/"off" after it would read "Servo on
    on")."""
    f = _BY_NAME.get(name)
    label = f.description if f is not None else name
    return f"{label} flag {'set' if value else 'cleared'}"

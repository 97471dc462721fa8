"""Layer: service. What a write (``service.writes.pipeline``) asks for, checked whole, and how the
robot's own frame confirms it. Pure: no I/O.

Validation goes through ``cobot_hmi.codec.command_from_json`` (known fields, indexes in range,
booleans for bits, 0/1 for types, finite numbers) one field at a time so that the error names
the field (a name that is not an O→T field, or anything the codec's checks let through that
still cannot be read, is this field's error too, never an exception), then checks each analog
output that the request touches (its value or its type) against
``layout.ANALOG_OUTPUT_RANGES`` for the type it will have after the request.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Final

from cobot_hmi.codec import CodecError, CommandImage, Frame, command_from_json
from cobot_hmi.layout import (
    ANALOG_OUTPUT_RANGES,
    FRAME_ECHOED,
    O2T_ASSEMBLY,
    Direction,
    field_by_name,
)

Path = tuple[str, int]
"""A touched element: field name and index."""

_TYPE_NAMES: Final = field_by_name(Direction.O_TO_T, "analog_output_type").value_names
_O2T_NAMES: Final = tuple(f.name for f in O2T_ASSEMBLY.fields)

_INDEX_IN_MESSAGE: Final = re.compile(r"^(\w+)\[(\d+)\]")


class WriteValidationError(ValueError):
    """A request that cannot be applied; ``field`` is ``name.index``, ``name`` or ``None``."""

    def __init__(self, field: str | None, reason: str) -> None:
        super().__init__(reason)
        self.field = field
        self.reason = reason


@dataclass(frozen=True, slots=True)
class PlannedWrite:
    image: CommandImage
    """The whole O→T image after the write."""
    paths: tuple[Path, ...]
    """Elements the request names, in layout order."""

    @property
    def field_names(self) -> list[str]:
        return [f"{name}.{index}" for name, index in self.paths]

    def values(self, image: CommandImage) -> dict[str, object]:
        """The touched elements' values in ``image`` (``before`` / ``requested`` in the audit)."""
        return {f"{n}.{i}": getattr(image, n)[i] for n, i in self.paths}

    @property
    def by_frame(self) -> tuple[Path, ...]:
        return tuple(p for p in self.paths if p[0] in FRAME_ECHOED)

    @property
    def by_packet(self) -> tuple[Path, ...]:
        return tuple(p for p in self.paths if p[0] not in FRAME_ECHOED)


def _paths(name: str, value: object) -> list[Path]:
    count = field_by_name(Direction.O_TO_T, name).count
    if isinstance(value, Mapping):
        return sorted((name, int(str(k))) for k in value)
    return [(name, i) for i in range(count)]


def plan_write(body: object, base: CommandImage) -> PlannedWrite:
    """Check ``body`` whole against ``base`` (the image being sent); ``WriteValidationError`` if any
    part is wrong, so nothing is half-applied."""
    if not isinstance(body, Mapping):
        raise WriteValidationError(None, "the body must be a JSON object of fields")
    if not body:
        raise WriteValidationError(None, "nothing to write: give at least one field")
    paths: list[Path] = []
    for name, value in body.items():
        if name not in _O2T_NAMES:  # also the frame-only keys the codec tolerates ("extra")
            known = ", ".join(_O2T_NAMES)
            raise WriteValidationError(
                str(name), f"unknown field {name!r}: a write names O→T fields ({known})"
            )
        try:
            command_from_json({name: value}, base)
            paths.extend(_paths(name, value))
        except CodecError as error:
            message = str(error)
            match = _INDEX_IN_MESSAGE.match(message)
            field = f"{name}.{match.group(2)}" if match and match.group(1) == name else name
            raise WriteValidationError(field, message) from None
        except (ValueError, TypeError, OverflowError) as error:
            # Whatever slips past the codec's checks is still this field's fault, never a 500.
            raise WriteValidationError(name, f"{name}: {error}") from None
    image = command_from_json(body, base)
    touched = {p for p in paths if p[0] in ("analog_output", "analog_output_type")}
    for index in sorted({i for _, i in touched}):
        type_code = image.analog_output_type[index]
        low, high, unit = ANALOG_OUTPUT_RANGES[_TYPE_NAMES[type_code]]
        value = image.analog_output[index]
        if not low <= value <= high:
            reason = (
                f"analog_output[{index}]: {value} is outside {low:g}–{high:g} {unit} "
                f"({_TYPE_NAMES[type_code]})"
            )
            if ("analog_output", index) not in touched:
                reason += "; give a value in range together with the type change"
            raise WriteValidationError(f"analog_output.{index}", reason)
    order = {name: i for i, name in enumerate(_O2T_NAMES)}
    unique = sorted(set(paths), key=lambda p: (order[p[0]], p[1]))
    return PlannedWrite(image, tuple(unique))


def _analog_tolerance(type_code: int) -> float:
    # The frame's analog output is the robot's actual value; allow 0.5 % of the range so a
    # real controller's rounding still confirms, while a wrong value never does.
    low, high, _ = ANALOG_OUTPUT_RANGES[_TYPE_NAMES[type_code]]
    return 0.005 * (high - low)


def frame_shows(frame: Frame, image: CommandImage, paths: tuple[Path, ...]) -> bool:
    """Whether the robot's frame reports the commanded value of every path."""
    for name, index in paths:
        actual = getattr(frame, name)[index]
        wanted = getattr(image, name)[index]
        if isinstance(wanted, float):
            tolerance = _analog_tolerance(image.analog_output_type[index])
            if not (math.isfinite(actual) and abs(actual - wanted) <= tolerance):
                return False
        elif actual != wanted:
            return False
    return True


def robot_reports(frame: Frame | None, paths: tuple[Path, ...]) -> dict[str, object]:
    """What the frame shows for ``paths`` (the 504 answer); ``None`` without a frame."""
    return {
        f"{n}.{i}": (None if frame is None else _json_value(getattr(frame, n)[i])) for n, i in paths
    }


def _json_value(value: object) -> object:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value

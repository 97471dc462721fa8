"""Layer: service. The API's contract: The frame and command-image models, built from the layout at
import, and the JSON values they share."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Any, Final, Literal, TypeAlias

from pydantic import BaseModel, ConfigDict, Field, StringConstraints, create_model
from typing_extensions import TypeAliasType

from cobot_hmi.layout import (
    O2T_ASSEMBLY,
    ROBOT_STATES,
    T2O_ASSEMBLY,
    UNKNOWN_STATE_NAME,
    Assembly,
    flag_fields,
)
from cobot_hmi.layout import Field as LayoutField

# --------------------------------------------------------------------------- JSON values

Json = TypeAliasType("Json", "bool | int | float | str | list[Json] | dict[str, Json] | None")
"""Any JSON document (what an audit row keeps of a body), typed so that its schema is never
empty: one recursive component."""

ElementValue: TypeAlias = bool | int | float | None
"""One element of an O→T or T→O field (``null``: a non-finite REAL)."""


def index_pattern(count: int) -> str:
    """A regular expression for the decimal indexes ``0 … count-1`` (ASCII, no leading zeros):
    the keys of a partial write, so a fuzzer produces only valid ones."""
    return "^(?:" + "|".join(str(i) for i in range(count)) + ")$"


def element_key(name: str, count: int) -> str:
    """``name.index`` keys as the audit and a 504 answer use them."""
    return f"^{name}\\.(?:" + "|".join(str(i) for i in range(count)) + ")$"


ROBOT_NAME_PATTERN: Final = r"^[a-z0-9][a-z0-9_-]{0,31}$"
"""A robot's name (settings), as it appears in paths and ``?robot=``."""

RobotName = Annotated[str, StringConstraints(pattern=ROBOT_NAME_PATTERN)]

STATE_NAMES: Final = (*(s.name for s in ROBOT_STATES), UNKNOWN_STATE_NAME)
RobotStateName = Literal[STATE_NAMES]  # type: ignore[valid-type]
FLAG_NAMES: Final = tuple(f.name for f in flag_fields())
FlagName = Literal[FLAG_NAMES]  # type: ignore[valid-type]


# --------------------------------------------------------------------------- layout-built


class ControllerVersion(BaseModel):
    """Controller software version (T→O bytes 28–30)."""

    major: int = Field(ge=0, le=255)
    minor: int = Field(ge=0, le=255)
    patch: int = Field(ge=0, le=255)


def _element_type(f: LayoutField, *, written: bool = False) -> Any:
    """An element's type; ``written``: as a write gives it (a finite number, never null)."""
    kind = f.value_kind
    if kind == "bool":
        return bool
    if kind == "int":
        top = len(f.value_names) - 1 if f.value_names else 255
        return Annotated[int, Field(ge=0, le=top)]
    return float if written else float | None  # a non-finite REAL is sent as null


def _describe(f: LayoutField) -> str:
    parts = [f.description]
    if f.unit:
        parts.append(f"unit: {f.unit}")
    if f.value_names:
        parts.append("coding: " + ", ".join(f"{i} = {n}" for i, n in enumerate(f.value_names)))
    if f.channels:
        parts.append(f"index 0 is {f.channels[0]}, index {f.count - 1} is {f.channels[-1]}")
    return "; ".join(parts)


def _full_field(f: LayoutField) -> tuple[Any, Any]:
    """The whole value of a field as decoded: an array of ``count``, a scalar or a record."""
    if f.element_names:
        return ControllerVersion, Field(description=_describe(f))
    element = _element_type(f)
    if f.scalar:
        return element, Field(description=_describe(f))
    return list[element], Field(  # type: ignore[valid-type]
        min_length=f.count, max_length=f.count, description=_describe(f)
    )


def _assembly_fields(assembly: Assembly) -> dict[str, Any]:
    fields: dict[str, Any] = {}
    for f in assembly.fields:
        fields[f.name] = _full_field(f)
        if f.enum:
            fields[f"{f.name}_name"] = (
                RobotStateName,
                Field(description=f"{f.description}: its name ({UNKNOWN_STATE_NAME} if unknown)"),
            )
    return fields


def _partial_field(f: LayoutField) -> tuple[Any, Any]:
    """A partial write of a field: a map from index (as text) to the new value."""
    key: Any = Annotated[str, StringConstraints(pattern=index_pattern(f.count))]
    value: Any = _element_type(f, written=True)
    return (
        dict[key, value],
        Field(  # absent: unchanged (the schema says no null: a null is refused)
            default=None,
            description=f"{_describe(f)}. A map from index to value, e.g. "
            f'{{"0": …}} writes {f.channels[0] if f.channels else "element 0"}',
            json_schema_extra={"additionalProperties": False},
        ),
    )


_STRICT = ConfigDict(extra="forbid")

if TYPE_CHECKING:  # mypy sees plain models; at run time they are built from the layout

    class Frame(BaseModel):
        robot_state: int

    class SubscribedFrame(BaseModel):
        pass

    class CommandImage(BaseModel):
        pass

    class CommandPatch(BaseModel):
        pass

else:
    Frame = create_model(
        "Frame",
        __doc__=T2O_ASSEMBLY.description + f" ({T2O_ASSEMBLY.size_bytes} bytes), decoded.",
        __config__=_STRICT,
        **_assembly_fields(T2O_ASSEMBLY),
        extra=(
            Annotated[str, StringConstraints(pattern="^(?:[0-9a-f]{2})*$")] | None,
            Field(default=None, description="bytes past the layout's size, hex (rare)"),
        ),
    )
    SubscribedFrame = create_model(
        "SubscribedFrame",
        __doc__="The fields of a frame a client's subscription asked for (WebSocket "
        "`subscribe`): each as in Frame, the others absent.",
        __config__=_STRICT,
        **{
            name: (annotation | None, Field(default=None, description=info.description))
            for name, (annotation, info) in _assembly_fields(T2O_ASSEMBLY).items()
        },
    )
    CommandImage = create_model(
        "CommandImage",
        __doc__=O2T_ASSEMBLY.description + f" ({O2T_ASSEMBLY.size_bytes} bytes), whole.",
        __config__=_STRICT,
        **_assembly_fields(O2T_ASSEMBLY),
    )
    CommandPatch = create_model(
        "CommandPatch",
        __doc__="Part of the O→T image to write: per field, a map from index to value. "
        "Validated whole before anything changes.",
        __config__=_STRICT,
        **{f.name: _partial_field(f) for f in O2T_ASSEMBLY.fields},
    )

COMMAND_PATCH_EXAMPLE: Final[dict[str, dict[str, object]]] = {
    "controlbox_do": {"2": True},
    "tool_do": {"0": False},
    "analog_output": {"0": 12.5},
    "analog_output_type": {"0": 0},
    "bit_input_registers": {"40": True},
}
"""Index 2 of ``controlbox_do`` is DO 3; index 0 of ``tool_do`` is Tool DO 1."""

_ELEMENT_KEYS: Final = "|".join(
    f"{f.name}\\.(?:{'|'.join(str(i) for i in range(f.count))})" for f in O2T_ASSEMBLY.fields
)
ElementKey = Annotated[str, StringConstraints(pattern=f"^(?:{_ELEMENT_KEYS})$")]
"""``name.index`` of one O→T element (``controlbox_do.2`` is DO 3)."""

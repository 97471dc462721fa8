"""Layer: service. The API's contract: a Pydantic model for every JSON answer, request body and
WebSocket message, so ``/openapi.json`` describes all of it (no empty schema) and clients can be
generated from it.

The frame and command-image models are built from ``cobot_hmi.layout`` at import (one place:
a field added to the layout appears here, with its count, element type and index pattern).
The models document and check shapes; the hot path does not go through them: the WebSocket
fan-out serializes each frame once with orjson (``service.robots.hub``), and the tests validate real
messages against these models. Imports the layout, the codec's constants and pydantic only.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Any, Final, Literal, TypeAlias

from pydantic import BaseModel, ConfigDict, Field, StringConstraints, TypeAdapter, create_model
from typing_extensions import TypeAliasType

from cobot_hmi.layout import (
    LAYOUT_VERSION,
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


# --------------------------------------------------------------------------- errors


class ApiErrorBody(BaseModel):
    """Why a request was refused."""

    reason: str = Field(description="the refusal in words")
    field: str | None = Field(
        default=None,
        description="the part of the request at fault (``analog_output.0``, ``name``, a query "
        "parameter), when one is",
    )
    robot_reports: dict[str, ElementValue] | None = Field(
        default=None, description="504 only: what the robot's latest frame shows per element"
    )
    known: list[str] | None = Field(default=None, description="404 of a robot: the known names")


class ApiErrorResponse(BaseModel):
    """Every error answer: ``{"detail": {"reason": …, "field": …}}``."""

    detail: ApiErrorBody


# --------------------------------------------------------------------------- status


ConnectionState = Literal["idle", "connecting", "connected", "lost", "refused"]
Mode = Literal["exclusive_owner", "input_only"]


class ConnectionStatus(BaseModel):
    """A robot's class 1 connection: state, counters, receive interval statistics."""

    state: ConnectionState
    reason: str | None = Field(description="why the state is what it is, when it is not plain")
    robot: str = Field(description="the robot's address (host)")
    mode: Mode
    rpi_ms: float = Field(description="requested packet interval, ms")
    packets_in: int = Field(ge=0)
    packets_out: int = Field(ge=0)
    gaps: int = Field(
        ge=0, description="T→O packets lost on the way (CIP sequence count jumps past one)"
    )
    duplicates: int = Field(ge=0, description="T→O packets repeating the count (no new data)")
    late: int = Field(
        ge=0,
        description="T→O frames more than 1.5 × the granted T→O interval after the one before, "
        "for whatever reason: a gap, duplicates or a robot slower than its grant",
    )
    malformed: int = Field(ge=0)
    interval_mean_ms: float | None
    interval_p99_ms: float | None
    interval_max_ms: float | None
    last_frame_age_s: float | None
    stale: bool
    connected_since: float | None
    gaps_per_min: float | None = Field(
        default=None,
        description="T→O sequence gaps in the last minute (null: not connected, or no sample yet)",
    )
    packet_loss_high: bool = Field(
        default=False,
        description="the packet loss alarm is active: gaps_per_min is above "
        "alarm_gap_rate_per_min (the connection badge turns amber)",
    )
    slow_target: str | None = Field(
        default=None,
        description='the robot sends T→O less often than it granted, in words ("the robot '
        'grants 2 ms but sends every 10 ms"; median over a second above 1.5 × the grant); '
        "null while it keeps its grant",
    )


class User(BaseModel):
    """A logged-in user (or an API token's pseudo-user ``token:NAME``) and its role."""

    name: str
    role: Literal["viewer", "operator", "admin"] = Field(
        description="viewer reads; operator also takes control and writes; admin also names tags"
    )


class Me(BaseModel):
    """Who this request's session belongs to (null: no session)."""

    user: User | None


class LoginAnswer(BaseModel):
    """A new session: its user, and its bearer token (also set as the session cookie)."""

    user: User
    token: str = Field(description="send as `Authorization: Bearer …` from scripts")


class Holder(BaseModel):
    user: str
    since: float = Field(description="when control was taken, s since the epoch")
    session: str | None = Field(
        default=None,
        description="the public id of the login session holding control (never its token); "
        "compare with the hello's `session` to tell this window from another one of the "
        "same user",
    )
    session_is_yours: bool | None = Field(
        default=None,
        description="answers to one request (GET …/status, …/robots, the hello): true when the "
        "requesting session holds control, false when another session does (possibly the "
        "same user's, in another window: only the holding session may write or release); "
        "null when the request has no session, and in events",
    )


class ControlStatus(BaseModel):
    """Who holds control of a robot's outputs (``null``: nobody; O→T is idle)."""

    holder: Holder | None


class RobotStatus(BaseModel):
    """``GET …/status``: the connection and control of one robot."""

    connection: ConnectionStatus
    control: ControlStatus


AlarmStateName = Literal[
    "normal",
    "active_unacknowledged",
    "active_acknowledged",
    "returned_unacknowledged",
    "suppressed",
]


class Identity(BaseModel):
    """The robot's CIP Identity object (Vol 1 §5A-2), when it was read."""

    vendor_id: int
    device_type: int
    product_code: int
    revision: str = Field(description="major.minor")
    serial_number: int
    product_name: str


AlarmPriority = Literal["critical", "high", "medium", "low"]


class AlarmBrief(BaseModel):
    """An alarm named in a few fields (the most urgent of a robot or of the cell): the fields of
    ``Alarm`` a banner line needs, in the service's words."""

    id: str = Field(description="``robot:key``")
    robot: str
    key: str
    name: str = Field(description='in words: "Emergency stop"')
    priority: AlarmPriority
    priority_rank: int = Field(ge=0, le=3)
    colour: str
    state: AlarmStateName
    active: bool
    label: str | None
    tag: str | None
    message: str | None = Field(description="the condition in words at the last change")
    activated_at: float | None
    changed_at: float | None


class PriorityCounts(BaseModel):
    """Annunciated alarms of one priority (not normal, not shelved, not suppressed)."""

    annunciated: int = Field(ge=0, description="what a banner counts: active or unacknowledged")
    active: int = Field(ge=0, description="of those, the condition is there")
    unacknowledged: int = Field(ge=0, description="of those, nobody acknowledged them yet")


class AlarmSummary(BaseModel):
    """A robot's alarms at a glance (the fleet tile, the robot switcher's mark, a banner line
    naming another robot)."""

    robot: str | None = Field(default=None, description="the robot's name")
    active: int = Field(ge=0, description="the condition is there (shelved and suppressed too)")
    unacknowledged: int = Field(ge=0)
    shelved: int = Field(ge=0)
    suppressed: int = Field(
        default=0, ge=0, description="consequences of another alarm, suppressed by design"
    )
    annunciated: int = Field(
        default=0,
        ge=0,
        description="alarms a person must see: not normal, not shelved, not suppressed",
    )
    highest_priority: AlarmPriority | None = Field(
        description="the most urgent priority of the annunciated alarms"
    )
    by_priority: dict[AlarmPriority, PriorityCounts] | None = Field(
        default=None, description="annunciated alarms per priority (every priority present)"
    )
    top: AlarmBrief | None = Field(
        default=None,
        description="the most urgent annunciated alarm (active before returned, then priority, "
        "then the newest change), null: none",
    )


class CellAlarmSummary(BaseModel):
    """``GET /api/v1/alarms/summary`` and the stream's status ``cell_alarms``: every robot's
    alarms at a glance, and the cell's most urgent annunciated alarm."""

    robots: list[AlarmSummary] = Field(description="every robot, in the settings' order")
    annunciated: int = Field(ge=0, description="annunciated alarms of every robot")
    highest_priority: AlarmPriority | None
    top: AlarmBrief | None = Field(description="the cell's most urgent annunciated alarm")


class RobotSummary(BaseModel):
    """One robot of the cell in ``GET /api/v1/robots``."""

    name: RobotName
    host: str
    mode: Mode
    rpi_ms: float
    model: str | None = Field(description="the product name from its identity, when known")
    identity: Identity | None
    connection: ConnectionState
    connection_reason: str | None
    holder: Holder | None = Field(description="who holds control (null: nobody)")
    robot_state: int | None = Field(description="the latest frame's robot state, if any")
    robot_state_name: RobotStateName | None
    default: bool = Field(description="the robot the deprecated single-robot paths answer for")
    alarms: AlarmSummary | None = Field(
        default=None, description="its alarms at a glance (GET /api/v1/alarms?robot= for them)"
    )
    frame_age_s: float | None = Field(
        default=None, description="how old the newest frame is, s (null: no frame yet)"
    )
    stale: bool = Field(
        default=True,
        description="not connected, or no frame for longer than stale_after_ms",
    )
    gaps: int | None = Field(
        default=None,
        ge=0,
        description="T→O packets lost on the way on the current connection, at the last 0.5 s "
        "alarm tick (null: not connected)",
    )
    gaps_per_min: float | None = Field(
        default=None, description="T→O sequence gaps in the last minute (null: not connected)"
    )
    packet_loss_high: bool = Field(
        default=False, description="the packet loss alarm is active (gaps_per_min too high)"
    )


class RobotList(BaseModel):
    robots: list[RobotSummary]


class FrameAnswer(BaseModel):
    """``GET …/frame``: the newest decoded frame and how old it is."""

    robot: RobotName
    frame: Frame | None
    received_at: float | None
    age_s: float | None
    stale: bool


class CommandState(BaseModel):
    """``GET …/command``: the O→T image being sent and whether its run/idle header says run."""

    robot: RobotName
    image: CommandImage
    run: bool


class WriteConfirmed(BaseModel):
    """``PATCH …/command``: applied, and the robot showed it."""

    outcome: Literal["confirmed"]
    image: CommandImage
    latency_ms: float
    audit_pending: bool = Field(
        False,
        description="true: the audit trail could not be written (a full disk); this write's "
        "audit row waits in the service's memory and is written as soon as there is room",
    )
    warning: str | None = Field(None, description="with audit_pending: that, in words")


class Health(BaseModel):
    ok: bool
    problems: list[str] = Field(
        default_factory=list, description="why not ok: a dead cyclic thread, a link down too long"
    )


class Ready(BaseModel):
    ready: bool
    reason: str | None = None
    robot: str | None = None


# --------------------------------------------------------------------------- events


class _EventBase(BaseModel):
    time: float = Field(description="s since the epoch")
    text: str = Field(
        description="the event in words, as the service says it everywhere (the event log, "
        'its CSV, exports): "Servo on flag cleared", "Emergency stop activated: robot state '
        'Emergency stop, Emergency stopped flag set"'
    )
    robot: str | None = Field(default=None, description="the robot's name")
    id: int | None = Field(default=None, description="row id in the event log (log pages only)")


class ConnectionEvent(_EventBase):
    kind: Literal["connection"]
    state: ConnectionState
    reason: str | None = None


class RobotStateEvent(_EventBase):
    model_config = ConfigDict(populate_by_name=True)

    kind: Literal["robot_state"]
    from_: int | None = Field(alias="from", description="previous state (null: the first frame)")
    to: int
    from_name: RobotStateName | None
    to_name: RobotStateName


class FlagEvent(_EventBase):
    kind: Literal["flag"]
    flag: FlagName
    value: bool
    label: str | None = Field(default=None, description='the flag in words ("Servo on")')


WriteOutcomeName = Literal[
    "confirmed", "timeout", "invalid", "refused", "unauthorized", "forbidden", "pending"
]


class WriteEvent(_EventBase):
    kind: Literal["write"]
    user: str | None
    fields: list[str] = Field(description="``name.index`` keys (0-based: controlbox_do.2 is DO 3)")
    outcome: WriteOutcomeName
    reason: str | None = None
    values: dict[str, ElementValue] | None = Field(
        default=None, description="the values written, by ``name.index`` key"
    )
    labels: dict[str, str] | None = Field(
        default=None,
        description="the spec's label of each key: controlbox_do.2 → DO 3, "
        "analog_output_type.1 → AO 1 type",
    )
    tags: dict[str, str] | None = Field(
        default=None, description="tag names of the touched points, where one is given"
    )
    summary: str | None = Field(
        default=None,
        description='the write in words with labels, tags and units: "AO 1 type = voltage, '
        'AO 1 = 5 V"',
    )


class ControlEvent(_EventBase):
    kind: Literal["control"]
    holder: Holder | None
    reason: str | None = None


AlarmTransition = Literal[
    "activated", "cleared", "acknowledged", "shelved", "unshelved", "shelve_expired"
]


class Alarm(BaseModel):
    """One alarm of one robot and its ISA-18.2 state (docs/api.md "Alarms")."""

    id: str = Field(description="``robot:key``, e.g. ``left:emergency_stop``")
    robot: str
    key: str = Field(
        description="emergency_stop, protective_stop, safe_off, connection_lost, "
        "forward_open_refused, packet_loss, recording_paused, motor_temperature.0–5 (0-based: "
        "motor_temperature.2 is J 3), user.NAME"
    )
    name: str = Field(description="in words")
    description: str
    priority: AlarmPriority
    priority_rank: int = Field(ge=0, le=3, description="0 critical … 3 low: sort by it")
    colour: str = Field(
        description="the pendant's colour: a robot state's own, else the priority's (critical "
        "red, high orange, medium yellow, low blue)"
    )
    kind: Literal["state", "connection", "rate", "limit", "bit", "recording"]
    element: str | None = Field(description="the watched frame element, ``name.index``")
    label: str | None = Field(description="its label as the robot prints it (J 3, DO 3)")
    tag: str | None = Field(description="its tag name, when an admin gave one")
    unit: str
    high: float | None
    low: float | None
    state: AlarmStateName = Field(
        description="ISA-18.2: normal, active_unacknowledged, active_acknowledged, "
        "returned_unacknowledged, or suppressed (by design: the condition is there as the "
        "consequence of the alarm suppressed_by names; not annunciated, nothing to acknowledge)"
    )
    active: bool = Field(description="the condition is there (state active_* or suppressed)")
    acknowledged: bool = Field(
        description="nothing to acknowledge: state normal, active_acknowledged or suppressed"
    )
    shelved: bool
    changed_at: float | None = Field(description="last change of this record, s since the epoch")
    activated_at: float | None
    cleared_at: float | None
    acknowledged_at: float | None
    acknowledged_by: str | None
    ack_comment: str | None
    shelved_until: float | None
    shelved_by: str | None
    shelve_reason: str | None
    value: bool | float | None = Field(description="the watched value at the last change")
    message: str | None = Field(description="the condition in words at the last change")
    suppressed_by: str | None = Field(
        default=None,
        description="the id of the alarm whose consequence this one's current (or last) "
        "activation is (state suppressed while it holds): group it under that alarm",
    )
    suppressed_by_name: str | None = Field(default=None, description="that alarm's name in words")


class AlarmList(BaseModel):
    """``GET /api/v1/alarms``: alarms that are active or unacknowledged, most urgent first."""

    items: list[Alarm]
    total: int = Field(ge=0)


class AlarmEvent(_EventBase):
    """An alarm changed: it came, went, was acknowledged, shelved or unshelved."""

    kind: Literal["alarm"]
    transition: AlarmTransition
    user: str | None = Field(default=None, description="who acknowledged or shelved it")
    comment: str | None = Field(default=None, description="the comment or shelving reason")
    alarm: Alarm


class AlarmHistoryRow(BaseModel):
    """One transition of one alarm."""

    id: int
    time: float = Field(description="s since the epoch (CSV: ISO 8601 with offset)")
    robot: str
    alarm_id: str
    key: str
    name: str
    priority: AlarmPriority
    transition: AlarmTransition
    state: AlarmStateName = Field(description="the state after the transition")
    shelved: bool
    message: str | None
    value: bool | float | None
    label: str | None
    tag: str | None
    user: str | None
    comment: str | None
    suppressed_by: str | None = Field(
        default=None, description="state suppressed: the id of the alarm it is a consequence of"
    )


class AlarmHistoryPage(BaseModel):
    items: list[AlarmHistoryRow]
    total: int = Field(ge=0)


class AlarmAck(BaseModel):
    """``POST /api/v1/alarms/{id}/ack`` (the body is optional)."""

    model_config = _STRICT

    comment: str | None = Field(default=None, max_length=500)


class AlarmShelve(BaseModel):
    """``POST /api/v1/alarms/{id}/shelve``."""

    model_config = _STRICT

    reason: str = Field(min_length=1, max_length=500, description="why (required)")
    duration_s: float = Field(
        gt=0,
        allow_inf_nan=False,
        description="until it unshelves itself, s (at most alarm_shelve_max_s)",
    )


class AlarmAnswer(BaseModel):
    """An operator's change of one alarm: the alarm after it, and whether anything changed."""

    alarm: Alarm
    changed: bool


ALARM_ACK_MAX: Final = 200
"""Most alarms one ``POST /api/v1/alarms/ack`` names (every robot's alarms fit many times)."""


class AlarmAckMany(BaseModel):
    """``POST /api/v1/alarms/ack``: acknowledge the alarms named (``ids``), or every
    unacknowledged, annunciated alarm of one robot (``robot``); exactly one of the two."""

    model_config = _STRICT

    ids: list[str] | None = Field(
        default=None,
        min_length=1,
        max_length=ALARM_ACK_MAX,
        description="alarm ids (``robot:key``), e.g. the ones a list shows",
    )
    robot: RobotName | None = Field(
        default=None,
        description="every alarm of this robot that is unacknowledged and annunciated (not "
        "shelved, not suppressed), as of the request",
    )
    comment: str | None = Field(default=None, max_length=500, description="for every one")


class AlarmAckResult(BaseModel):
    """What became of one alarm of an ``AlarmAckMany`` (each its own audit row)."""

    id: str
    outcome: Literal["acknowledged", "unchanged", "refused"] = Field(
        description="acknowledged; unchanged (nothing left to acknowledge: acknowledged "
        "already, or suppressed); refused (normal: nothing to acknowledge, the reason says)"
    )
    reason: str | None = None
    alarm: Alarm = Field(description="the alarm after it")


class AlarmAckManyAnswer(BaseModel):
    """``POST /api/v1/alarms/ack``: one result per alarm, in the order asked."""

    items: list[AlarmAckResult]
    acknowledged: int = Field(ge=0, description="how many changed")


class SessionEvent(_EventBase):
    """A session ended while it had streams of this robot open: they were closed (1008)."""

    kind: Literal["session"]
    user: str = Field(description="the session's user (``token:NAME`` for an API token)")
    session: str = Field(description="the session's public id (never its token)")
    reason: str = Field(
        description="why: logged out, session expired, the user removed or given another "
        "role, the API token revoked, expired or changed"
    )
    streams_closed: int = Field(ge=1, description="this robot's streams of it, closed")


class RecordingEvent(_EventBase):
    """The history recorder paused (disk full, write error), resumed, or fell behind."""

    kind: Literal["recording"]
    state: Literal["recording", "paused", "overflow"]
    reason: str | None = None
    dropped: int | None = Field(default=None, description="overflow: frames not recorded")


Event = Annotated[
    ConnectionEvent
    | RobotStateEvent
    | FlagEvent
    | WriteEvent
    | ControlEvent
    | RecordingEvent
    | AlarmEvent
    | SessionEvent,
    Field(discriminator="kind"),
]
EventKind = Literal[
    "connection", "robot_state", "flag", "write", "control", "recording", "alarm", "session"
]


class EventPage(BaseModel):
    """Events, newest first (each with its log ``id``)."""

    items: list[Event]
    total: int = Field(ge=0)


# --------------------------------------------------------------------------- audit

AuditAction = Literal[
    "write",
    "control.take",
    "control.release",
    "alarm.ack",
    "alarm.shelve",
    "alarm.unshelve",
    "tags.update",
    "checkout.start",
    "checkout.result",
    "checkout.capture",
    "checkout.close",
    "preset.save",
    "preset.delete",
]
AuditOutcome = Literal[
    "confirmed",
    "timeout",
    "invalid",
    "refused",
    "unauthorized",
    "forbidden",
    "granted",
    "released",
    "pending",
    "acknowledged",
    "shelved",
    "unshelved",
    "updated",
    "unchanged",
    "started",
    "recorded",
    "captured",
    "closed",
    "saved",
    "deleted",
]


class AuditRow(BaseModel):
    """One write attempt or control change."""

    id: int
    time: float
    robot: str | None = Field(
        description="the robot's name (null: rows from before robots had names)"
    )
    user: str | None
    client: str | None = Field(description="the writer's address or client id")
    origin: str | None = Field(description="which door the request came through (HTTP route, …)")
    action: AuditAction
    fields: list[str] = Field(description="``name.index`` keys of the elements touched")
    before: dict[str, ElementValue] | None
    requested: Json = Field(description="the requested values (a malformed body: what came)")
    outcome: AuditOutcome
    reason: str | None
    summary: str | None = Field(
        default=None,
        description="what was asked in words with the spec's labels: "
        '"DO 3 (gripper close) = on", "AO 1 type = voltage, AO 1 = 5 V"',
    )
    labels: dict[str, str] = Field(
        default_factory=dict,
        description="the spec's label of each key of ``fields`` (controlbox_do.2 → DO 3)",
    )
    tags: dict[str, str] | None = Field(
        default=None, description="tag names of the touched points when the row was written"
    )
    seal_seq: int | None = Field(
        default=None,
        description="the row's place in the audit trail's hash chain, sealed when it became "
        "final (null: pending, sealed with its outcome)",
    )
    seal_hash: str | None = Field(
        default=None,
        description="SHA-256 (hex) over the row and the previous seal: ``cobot-hmi audit "
        "verify`` (docs/operations.md, Audit verify)",
    )


class AuditPage(BaseModel):
    items: list[AuditRow]
    total: int = Field(ge=0)


# --------------------------------------------------------------------------- tag names


class TagPoint(BaseModel):
    """A taggable point of one robot: I/O or a bit register."""

    key: str = Field(description="``name.index``, 0-based as the frame's arrays: controlbox_do.2")
    label: str = Field(description="the spec's label: DO 3")
    field: str
    index: int = Field(ge=0)
    directions: list[Literal["T2O", "O2T"]]
    name: str | None = Field(description="its tag name (null: none)")


class TagList(BaseModel):
    """``GET /api/v1/robots/{name}/tags``: every taggable point with its name."""

    robot: str
    points: list[TagPoint]
    tags: dict[str, str] = Field(description="``{key: name}`` of the named points only")


class TagUpdate(BaseModel):
    """``PUT /api/v1/robots/{name}/tags``: the whole set of names (a point left out has none)."""

    model_config = _STRICT

    tags: dict[str, str] = Field(
        description='``{"controlbox_do.2": "gripper close"}`` (index 2 is DO 3); an empty name '
        "removes one",
        examples=[{"controlbox_do.2": "gripper close", "bit_input_registers.40": "part ready"}],
    )


class TagImport(BaseModel):
    """``POST /api/v1/robots/{name}/tags/import``: CSV text (``key,label,name``, as the export),
    sent as JSON; replaces every name."""

    model_config = _STRICT

    csv: str = Field(max_length=200_000)


# --------------------------------------------------------------------------- WebSocket


class FrameItem(BaseModel):
    seq: int = Field(description="the service's frame counter for this robot: gaps are visible")
    t: float = Field(description="receive time, s since the epoch")
    t2o_sequence: int | None = Field(
        default=None,
        ge=0,
        le=0xFFFFFFFF,
        description="the encapsulation sequence number the frame's T→O packet carried on the "
        "wire (the robot raises it per packet: a step of more than one is packets the scanner "
        "did not deliver); the recording keeps it in its t2o_sequence column",
    )
    frame: Frame


class HelloMessage(BaseModel):
    type: Literal["hello"]
    robot: str | None = None
    session: str | None = Field(
        default=None,
        description="the public id of this stream's login session (null: none): control's "
        "holder.session equal to it means this window holds control",
    )
    layout_version: Literal[LAYOUT_VERSION]  # type: ignore[valid-type]
    connection: ConnectionStatus
    control: ControlStatus
    rate_hz: float | None
    alarms: list[Alarm] = Field(
        default_factory=list,
        description="the robot's alarms that are active or unacknowledged when the stream "
        "opens, most urgent first; changes follow as `alarm` events",
    )
    cell_alarms: CellAlarmSummary | None = Field(
        default=None,
        description="every robot's alarms at a glance when the stream opens; each `status` "
        "message brings them again",
    )


class FramesMessage(BaseModel):
    type: Literal["frames"]
    frames: list[FrameItem]


class DroppedMessage(BaseModel):
    type: Literal["dropped"]
    count: int = Field(gt=0)


class StatusMessage(BaseModel):
    type: Literal["status"]
    robot: str | None = None
    connection: ConnectionStatus
    cell_alarms: CellAlarmSummary | None = Field(
        default=None,
        description="every robot's alarms at a glance (as GET /api/v1/alarms/summary): a "
        "panel or kiosk of one robot shows the others' from it",
    )


class EventMessage(BaseModel):
    type: Literal["event"]
    event: Event


StreamMessage = Annotated[
    HelloMessage | FramesMessage | DroppedMessage | StatusMessage | EventMessage,
    Field(discriminator="type"),
]
STREAM_MESSAGE: Final = TypeAdapter(StreamMessage)
"""Validates one WebSocket message (tests; never the hot path)."""
EVENT: Final = TypeAdapter(Event)


# --------------------------------------------------------------------------- layout document


class FlagDoc(BaseModel):
    abbreviation: str
    full_name: str


class LayoutFieldDoc(BaseModel):
    name: str
    offset: int
    cip_type: Literal["BOOL", "USINT", "REAL"]
    count: int
    first_bit: int | None
    bit_count: int
    scalar: bool
    value_kind: Literal["bool", "int", "float"]
    unit: str
    group: str
    description: str
    channels: list[str]
    value_names: list[str] | None = None
    element_names: list[str] | None = None
    flag: FlagDoc | None = None
    enum: str | None = None


class AssemblyDoc(BaseModel):
    name: str
    direction: Literal["T2O", "O2T"]
    size_bytes: int
    default_instance: int
    description: str
    fields: list[LayoutFieldDoc]


class RobotStateDoc(BaseModel):
    value: int
    name: str
    label: str
    description: str
    pendant_colours: list[str]
    colour_from_table: bool


class RangeDoc(BaseModel):
    low: float
    high: float
    unit: str


class LayoutDocument(BaseModel):
    """``GET /api/v1/layout``: the I/O layout every other shape derives from."""

    layout_version: int
    assemblies: list[AssemblyDoc]
    robot_states: list[RobotStateDoc]
    unknown_state_name: str
    analog_output_ranges: dict[str, RangeDoc]


# --------------------------------------------------------------------------- history

HistoryValue = bool | int | float | None
"""An element's value: as its frame field has it; a non-finite REAL is ``null``."""


class HistorySeries(BaseModel):
    """One element of a history answer: ``values`` (mode raw) or ``min``/``max``/``first``/
    ``last`` (mode buckets), index for index with the answer's ``t``."""

    element: str = Field(description="the element's column name: joint_position.0, robot_state")
    field: str = Field(description="its layout field")
    label: str = Field(description="the channel's label (J1), else the field's description")
    unit: str
    values: list[HistoryValue] | None = None
    min: list[HistoryValue] | None = None
    max: list[HistoryValue] | None = None
    first: list[HistoryValue] | None = None
    last: list[HistoryValue] | None = None


class HistoryAnswer(BaseModel):
    """``GET /api/v1/robots/{name}/history``: a range decimated for a plot (docs/api.md)."""

    model_config = ConfigDict(populate_by_name=True)

    robot: str
    from_: float = Field(alias="from", description="the range asked, s since the epoch")
    to: float
    points: int = Field(description="buckets asked for")
    mode: Literal["raw", "buckets"] = Field(
        description="raw: every frame of the range (it holds no more than `points`); buckets: "
        "per bucket the min, max, first and last of each element"
    )
    bucket_s: float | None = Field(
        description="bucket width, s (buckets of a second or more start at whole multiples of "
        "it since the epoch)"
    )
    frames: int = Field(ge=0, description="frames the answer covers")
    t: list[float] = Field(
        description="raw: each frame's receive time; buckets: each non-empty bucket's start (s "
        "since the epoch)"
    )
    seq: list[int] | None = Field(default=None, description="raw: each frame's counter")
    t2o_sequence: list[int | None] | None = Field(
        default=None,
        description="raw: each frame's T→O wire sequence number (null for a frame recorded "
        "before the service kept it)",
    )
    count: list[int] | None = Field(default=None, description="buckets: frames per bucket")
    t_first: list[float] | None = Field(default=None, description="buckets: first frame's time")
    t_last: list[float] | None = Field(default=None, description="buckets: last frame's time")
    series: list[HistorySeries]
    recording: bool = Field(description="false while recording is paused or off")
    recording_paused_reason: str | None = None


class HistoryEvents(BaseModel):
    """``GET /api/v1/robots/{name}/history/events``: the robot's events of a range, oldest
    first, each as the stream carries it plus its log ``id``."""

    items: list[Event]
    truncated: bool = Field(
        description="the range holds more than `limit` events: these are its oldest `limit`"
    )


class HistoryStatus(BaseModel):
    """``GET /api/v1/robots/{name}/history/status``: what is recorded of the robot."""

    robot: str
    recording: bool = Field(description="false while recording is paused or off")
    recording_paused_reason: str | None = None
    first: float | None = Field(description="the oldest frame kept, s since the epoch")
    last: float | None = Field(description="the newest frame on disk, s since the epoch")
    segments: int = Field(ge=0, description="closed segments kept")
    bytes: int = Field(ge=0, description="the robot's recording on disk")
    retention_days: float
    retention_bytes: int = Field(description="the bound of every robot's recordings together")


ExportFormat = Literal["csv", "parquet", "mcap"]


WEBSOCKET_MODELS: Final = (StreamMessage,)
"""What ``app.openapi`` adds to the components though no HTTP route answers with it."""

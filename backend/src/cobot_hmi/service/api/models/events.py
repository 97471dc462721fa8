"""Layer: service. The API's contract: Events (robot state, flags, writes, control, alarms,
sessions, recording) and alarms."""

from __future__ import annotations

from typing import Annotated, Final, Literal

from pydantic import BaseModel, ConfigDict, Field

from cobot_hmi.service.api.models.frames import (
    _STRICT,
    ElementValue,
    FlagName,
    RobotName,
    RobotStateName,
)
from cobot_hmi.service.api.models.status import (
    AlarmPriority,
    AlarmStateName,
    ConnectionState,
    Holder,
)

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
        "motor_temperature.2 is J 3), health.1–6 (robot health's advice on J 1–6), user.NAME"
    )
    name: str = Field(description="in words")
    description: str
    priority: AlarmPriority
    priority_rank: int = Field(ge=0, le=4, description="0 critical … 3 low, 4 advisory: sort by it")
    colour: str = Field(
        description="the pendant's colour: a robot state's own, else the priority's (critical "
        "red, high orange, medium yellow, low blue, advisory grey)"
    )
    kind: Literal["state", "connection", "rate", "limit", "bit", "recording", "health"]
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
    shelve_max_s: float | None = Field(
        default=None,
        description="the longest it may be shelved, s (its priority's alarm_shelve_max_*_s); "
        "null: never shelved (a safety stop or a critical alarm, shelve_refusal says why)",
    )
    shelve_refusal: str | None = Field(
        default=None, description="why it is never shelved, in words; null: it may be"
    )
    changed_at: float | None = Field(description="last change of this record, s since the epoch")
    activated_at: float | None
    cleared_at: float | None
    acknowledged_at: float | None
    acknowledged_by: str | None
    ack_comment: str | None
    shelved_until: float | None
    shelved_at: float | None = Field(
        default=None,
        description="when it was shelved: a condition that clears after this and comes again "
        "ends the shelving (annunciated again)",
    )
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
    value_words: str | None = Field(
        default=None,
        description="the value as a person reads it: a state alarm's robot state by its label "
        '("Emergency stop"), a number with its unit ("81.2 °C"), a bit "on"/"off"',
    )
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
        description="until it unshelves itself, s (at most the alarm's shelve_max_s: its "
        "priority's alarm_shelve_max_*_s)",
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


class CycleEvent(_EventBase):
    """A cycle of the robot measured by its trigger (``cycle_trigger``): ``time`` is its start,
    announced once the next start ended it (``GET /api/v1/robots/{name}/cycles``)."""

    kind: Literal["cycle"]
    end: float = Field(description="s since the epoch: the next cycle's start")
    duration_s: float = Field(ge=0, description="s")


class HealthEventJoint(BaseModel):
    joint: int = Field(ge=1, le=6)
    verdict: Literal["ok", "watch", "act"]
    reason: str
    life_used_percent: float = Field(description="reducer life used, %")


class HealthEvent(_EventBase):
    """The robot's health changed (``service.health``): a joint's verdict, or a joint's life
    used by 0.1 %; also the first verdicts after the service started
    (``GET /api/v1/robots/{name}/health`` has every figure)."""

    kind: Literal["health"]
    verdict: Literal["ok", "watch", "act"] = Field(description="the worst of the joints'")
    maintenance_due: bool = Field(description="a joint reads watch or act")
    joints: list[HealthEventJoint] = Field(description="J1 first")


Event = Annotated[
    ConnectionEvent
    | RobotStateEvent
    | FlagEvent
    | WriteEvent
    | ControlEvent
    | RecordingEvent
    | AlarmEvent
    | SessionEvent
    | CycleEvent
    | HealthEvent,
    Field(discriminator="kind"),
]
EventKind = Literal[
    "connection",
    "robot_state",
    "flag",
    "write",
    "control",
    "recording",
    "alarm",
    "session",
    "cycle",
    "health",
]


class EventPage(BaseModel):
    """Events, newest first (each with its log ``id``)."""

    items: list[Event]
    total: int = Field(ge=0)

"""Layer: service. The API's contract: Status, login, control, identity, robots and their alarms at
a glance, health."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field

from cobot_hmi.service.api.models.frames import CommandImage, Frame, RobotName, RobotStateName

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
    idle_timeout_s: float | None = Field(
        default=None,
        description="a login session ends this long after its person's last action (session_"
        "ttl_s); null: no session, or an API token's (which never idles out)",
    )
    idle_expires_in_s: float | None = Field(
        default=None,
        description="seconds left before it idles out unless its person acts (a changing "
        "request, POST /api/v1/auth/activity); reads never renew it",
    )


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


AlarmPriority = Literal["critical", "high", "medium", "low", "advisory"]


class AlarmBrief(BaseModel):
    """An alarm named in a few fields (the most urgent of a robot or of the cell): the fields of
    ``Alarm`` a banner line needs, in the service's words."""

    id: str = Field(description="``robot:key``")
    robot: str
    key: str
    name: str = Field(description='in words: "Emergency stop"')
    priority: AlarmPriority
    priority_rank: int = Field(ge=0, le=4)
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
    seq: int | None = Field(
        None,
        description="the sequence number of the robot's frame that showed the write, as the "
        "stream numbers its frames (`seq`): a display holds the value written until it shows "
        "that frame or a newer one; null when no frame confirms it (bit input registers: the "
        "O→T packet that carried them)",
    )
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

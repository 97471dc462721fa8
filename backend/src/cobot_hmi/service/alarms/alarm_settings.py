"""Layer: service. Alarm settings: a user's own alarms (``[[alarms]]``) and the built-in alarms'
limits and timing."""

from __future__ import annotations

from typing import Final, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from cobot_hmi.service.setting_fields import RobotName, Seconds, setting

# --------------------------------------------------------------------------- alarms

ALARM_NAME_PATTERN: Final = r"^[a-z0-9][a-z0-9_-]{0,47}$"
AlarmPriority = Literal["critical", "high", "medium", "low"]


class AlarmSettings(BaseModel):
    """A user-defined alarm on one element of the robot's T→O frame (an ``[[alarms]]`` table):
    a number above ``high`` or below ``low`` (with ``deadband``), or a bit equal to
    ``active_when``; ``on_delay_s`` / ``off_delay_s`` before it comes / clears
    (docs/operations.md "Alarms")."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    name: str = Field(
        pattern=ALARM_NAME_PATTERN,
        description="the alarm's key (user.NAME in the API): lower-case letters, digits, _ and -",
    )
    field: str = Field(description="a T→O field of the layout (joint_motor_current, tool_di…)")
    index: int | None = Field(
        default=None,
        ge=0,
        description="the element's 0-based index in the frame's array (controlbox_di index 2 "
        "is DI 3); none for a scalar field",
    )
    robot: RobotName | None = Field(default=None, description="one robot (default: every robot)")
    high: float | None = Field(default=None, allow_inf_nan=False, description="above: active")
    low: float | None = Field(default=None, allow_inf_nan=False, description="below: active")
    active_when: bool | None = Field(default=None, description="a bit: the value that alarms")
    deadband: float = Field(default=0.0, ge=0, allow_inf_nan=False, description="hysteresis")
    on_delay_s: float = Field(default=0.0, ge=0, le=3600, allow_inf_nan=False)
    off_delay_s: float = Field(default=0.0, ge=0, le=3600, allow_inf_nan=False)
    priority: AlarmPriority = "medium"
    message: str = Field(default="", max_length=200, description="the alarm's name in words")

    @model_validator(mode="after")
    def _check_element(self) -> AlarmSettings:
        from cobot_hmi.layout import T2O_FIELDS

        fields = {f.name: f for f in T2O_FIELDS}
        f = fields.get(self.field)
        if f is None:
            raise ValueError(f"{self.field!r} is not a T→O field ({', '.join(fields)})")
        if f.element_names:
            raise ValueError(f"{self.field} is a record, not a number or a bit")
        single = f.scalar or f.count == 1
        if self.index is None and not single:
            raise ValueError(f"{self.field} has {f.count} elements: give index 0–{f.count - 1}")
        if self.index is not None and self.index >= f.count:
            raise ValueError(f"{self.field}: index {self.index} is not in 0–{f.count - 1}")
        if f.value_kind == "bool":
            if self.high is not None or self.low is not None or self.deadband:
                raise ValueError(f"{self.field} is a bit: give active_when, not high/low")
        else:
            if self.active_when is not None:
                raise ValueError(f"{self.field} is a number: give high and/or low")
            if self.high is None and self.low is None:
                raise ValueError(f"{self.field}: give high and/or low")
            if self.high is not None and self.low is not None and self.low >= self.high:
                raise ValueError(f"low ({self.low:g}) must be below high ({self.high:g})")
        return self


class AlarmLimitSettings(BaseModel):
    """The built-in alarms' limits and timing and the user's own alarms (``service.alarms``;
    docs/operations.md "Alarms")."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    # --- alarms (service/alarms; docs/operations.md "Alarms")
    alarms: list[AlarmSettings] = Field(
        default_factory=list,
        description="user-defined alarms ([[alarms]] tables; COBOT_HMI_ALARMS as a JSON list)",
    )
    alarm_motor_temperature_c: float = setting(
        80.0, "motor temperature alarm of each joint above this, °C", allow_inf_nan=False
    )
    alarm_motor_temperature_deadband_c: float = setting(
        2.0, "it clears this far below, °C", ge=0, allow_inf_nan=False
    )
    alarm_gap_rate_per_min: float = setting(
        10.0, "packet loss alarm: more T→O sequence gaps than this in a minute", ge=0
    )
    alarm_connection_delay_s: float = setting(
        2.0, "connection lost or stale this long raises its alarm, s", ge=0, le=3600
    )
    alarm_shelve_max_s: Seconds = setting(
        8 * 3600.0, "longest any alarm may be shelved (caps each priority's own longest), s"
    )
    # Critical alarms and the safety stops are never shelved (alarms/shelving.py).
    alarm_shelve_max_high_s: Seconds = setting(
        3600.0, "longest a high-priority alarm may be shelved, s"
    )
    alarm_shelve_max_medium_s: Seconds = setting(
        4 * 3600.0, "longest a medium-priority alarm may be shelved, s"
    )
    alarm_shelve_max_low_s: Seconds = setting(
        8 * 3600.0, "longest a low-priority alarm may be shelved, s"
    )
    alarm_consequence_window_s: float = setting(
        5.0,
        "an alarm coming this long after its cause cleared (or while the cause is active) is its "
        "consequence, suppressed by design (SAFE_OFF after an e-stop's reset), s",
        ge=0,
        le=600,
        allow_inf_nan=False,
    )

    @model_validator(mode="after")
    def _distinct_names(self) -> AlarmLimitSettings:
        names: set[str] = set()
        for alarm in self.alarms:
            if alarm.name in names:
                raise ValueError(f"alarms: the name {alarm.name!r} is given twice")
            names.add(alarm.name)
        return self

"""Layer: service. The API contract of robot health (``/api/v1/robots/{name}/health``, issue 40,
docs/health.md): Pydantic models as ``models.py`` writes the rest. The figures are the
engine's (``cobot_hmi.health.report``); their laws and limits are docs/health.md's."""

from __future__ import annotations

import time
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from cobot_hmi.service.api.search import epoch_s

PERIOD_MAX_DAYS = 7
_TIME_HELP = (
    "seconds since the epoch, or ISO 8601 (without an offset: the plant's time zone), as the "
    "other routes' from and to"
)

Verdict = Literal["ok", "watch", "act"]


class HealthRated(BaseModel):
    """The joint's rated values (``arms.py``), the reducer life law's references."""

    torque_nm: float
    speed_deg_s: float
    life_h: float
    assumed: bool = Field(description="true: not published by the maker, an assumption")


class HealthJoint(BaseModel):
    """One joint's verdict, its reason in a sentence and its figures (null: not measured yet)."""

    joint: int = Field(ge=1, le=6, description="1–6, as the robot labels its joints")
    verdict: Verdict
    reason: str = Field(
        description='in a sentence: "J3: friction 14 % above its baseline of 1 Dec at the '
        'same speed and temperature, rising 2.0 % a week"'
    )
    friction_percent: float | None = Field(
        description="friction against the baseline at the same position, speed and "
        "temperature band, %"
    )
    friction_percent_per_week: float | None = Field(description="its slope, % a week")
    friction_percent_since_first_baseline: float | None = Field(
        description="the same chained through every re-baselining since the first, %"
    )
    friction_reference: Literal["steady", "fitted"] | None = Field(
        description="where the healthy friction the % is of comes from"
    )
    signature_rms_percent: float | None = Field(
        description="the cycle's torque against the baseline's, RMS, % of the joint's RMS torque"
    )
    signature_distribution_percent: float | None = Field(
        description="the torque distribution's distance from the baseline's, %"
    )
    heat_excess_c: float | None = Field(
        description="the motor's temperature beyond what its current explains, °C"
    )
    life_used_percent: float = Field(description="reducer life used, %")
    life_remaining_h: float | None = Field(description="remaining life at this week's duty, h")
    life_end_date: str | None = Field(
        description="the date it runs out at that duty, YYYY-MM-DD; null when the duty is not "
        "known or the date lies more than 100 years ahead"
    )
    collisions_this_shift: int = Field(
        ge=0, description="external-torque peaks over the joint's threshold this shift"
    )
    rated: HealthRated


class HealthCycleTime(BaseModel):
    """The cycle time against the baseline's (a CUSUM detects a drift as it happens)."""

    verdict: Literal["ok", "watch"]
    reason: str
    baseline_s: float | None = Field(description="the baseline's mean cycle time, s")
    recent_s: float | None = None
    change_percent: float | None = None
    drift_detected: bool = False
    detected_at: float | None = Field(None, description="s since the epoch")
    cycles: int | None = None


class HealthKnock(BaseModel):
    """One knock: where in joint space it happened."""

    time: float = Field(description="s since the epoch")
    kind: Literal["collision", "protective_stop", "emergency_stop", "servo_off"]
    joint: int | None = Field(description="the joint of a collision (1–6); null for the others")
    external_torque_nm: float | None = Field(description="a collision's peak external torque")
    joint_position_deg: list[float] = Field(description="every joint's position then, J1 first")


class HealthKnocks(BaseModel):
    """This shift's knocks."""

    shift_start: float | None = Field(description="when this shift started, s since the epoch")
    collisions: list[int] = Field(description="per joint, J1 first")
    protective_stop: int = Field(ge=0)
    emergency_stop: int = Field(ge=0)
    servo_off: int = Field(ge=0)
    events: list[HealthKnock] = Field(description="the latest (at most 20), oldest first")


class HealthBaseline(BaseModel):
    """A baseline: the robot's healthy reference, who set it, why, from which cycles."""

    id: int = Field(ge=1, description="1 for the robot's first, counting up")
    reason: str
    created_by: str = Field(description="the user who asked for it")
    created_at: float = Field(description="when it was asked for, s since the epoch")
    arm: str = Field(description="the arm model it was learned on (M1013)")
    layout_version: int = Field(description="the I/O layout's version it was learned on")
    target_cycles: int | None = Field(description="the whole cycles it learns from")
    cycles: int | None = Field(description="the cycles it learned from (so far, while learning)")
    learned_from: float = Field(description="learning started, s since the epoch")
    learned_to: float | None = Field(description="learning finished; null: still learning")
    active: bool = Field(description="the verdicts are against this one")
    learning: bool = Field(description="being learned now")


class HealthReport(BaseModel):
    """A robot's health now: each joint's verdict and figures."""

    robot: str
    arm: str
    time: float = Field(description="s since the epoch")
    verdict: Verdict = Field(description="the worst of the joints'")
    maintenance_due: bool = Field(description="a joint reads watch or act")
    cycles: int = Field(ge=0, description="whole cycles the engine measured")
    dropped_frames: int = Field(
        ge=0,
        description="frames health left out: unusable ones (not a number, out of order) and "
        "those its queue dropped when it fell behind",
    )
    joints: list[HealthJoint] = Field(min_length=6, max_length=6, description="J1 first")
    cycle_time: HealthCycleTime
    knocks: HealthKnocks
    baseline: HealthBaseline | None = Field(description="the one in use; null: none yet")
    learning: HealthBaseline | None = Field(description="one being learned; null: none")


class HealthBaselineList(BaseModel):
    items: list[HealthBaseline] = Field(description="oldest first, the one learning last")


class HealthBaselineCreate(BaseModel):
    """Learn a new baseline (after a reducer change, a new program): from the next N whole
    cycles (``cycles``, the default), or from a period already recorded (``from`` and ``to``):
    one or the other, not both."""

    model_config = ConfigDict(populate_by_name=True)

    reason: str = Field(min_length=1, max_length=500, pattern=r"\S", description="why, in words")
    cycles: int | None = Field(
        None,
        ge=1,
        le=10_000,
        description="learn from the next N whole cycles of the cycle meter (default 50 when "
        "no period is given)",
    )
    from_: float | str | None = Field(
        None,
        alias="from",
        description="learn from the robot's recorded frames (history) and the cycles the cycle "
        f"meter stored from this time on: {_TIME_HELP}",
    )
    to: float | str | None = Field(
        None,
        description=f"… until this time: not in the future, at most {PERIOD_MAX_DAYS} days "
        "after from",
    )

    @model_validator(mode="after")
    def _one_way(self) -> HealthBaselineCreate:
        period = self.from_ is not None or self.to is not None
        if period and self.cycles is not None:
            raise ValueError("give either 'cycles' or 'from' and 'to', not both")
        if period and (self.from_ is None or self.to is None):
            missing = "from" if self.from_ is None else "to"
            raise ValueError(f"a period needs both 'from' and 'to': '{missing}' is missing")
        if period:
            self.period_s()
        return self

    def period_s(self) -> tuple[float, float]:
        """The period as seconds since the epoch; ``ValueError`` naming the field that is
        wrong."""
        times: list[float] = []
        for name, text in (("from", self.from_), ("to", self.to)):
            try:
                value = None if text is None else epoch_s(str(text))
            except ValueError as error:
                raise ValueError(f"'{name}': {error}") from None
            if value is None:
                raise ValueError(f"'{name}' is missing")
            times.append(value)
        from_s, to_s = times
        if to_s > time.time():
            raise ValueError("'to' is in the future: a baseline is learned from recorded frames")
        if from_s >= to_s:
            raise ValueError("'from' must be before 'to'")
        if to_s - from_s > PERIOD_MAX_DAYS * 86_400.0:
            raise ValueError(f"the period from 'from' to 'to' is over {PERIOD_MAX_DAYS} days")
        return from_s, to_s


class HealthTrendJoint(BaseModel):
    """One joint's figures in a snapshot."""

    joint: int = Field(ge=1, le=6)
    verdict: Verdict
    friction_percent: float | None
    friction_percent_since_first_baseline: float | None
    signature_rms_percent: float | None
    heat_excess_c: float | None
    life_used_percent: float | None
    life_remaining_h: float | None
    collisions_this_shift: int | None


class HealthTrendPoint(BaseModel):
    """The figures at one snapshot (every ``health_snapshot_s``)."""

    time: float = Field(description="s since the epoch")
    baseline_id: int | None = Field(description="the baseline the figures are against")
    verdict: Verdict
    cycles: int
    joints: list[HealthTrendJoint]


class HealthTrend(BaseModel):
    robot: str
    points: list[HealthTrendPoint] = Field(description="oldest first")

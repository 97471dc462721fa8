"""Layer: service. The API contract of cycle timing (``GET /api/v1/robots/{name}/cycles``):
Pydantic models as ``models.py`` writes the rest."""

from __future__ import annotations

from pydantic import BaseModel, Field


class CycleRow(BaseModel):
    """One measured cycle: from one trigger edge to the next (receive times of the frames)."""

    id: int
    start: float = Field(description="s since the epoch")
    end: float = Field(description="s since the epoch: the next cycle's start")
    duration_s: float = Field(ge=0)
    interrupted: bool = Field(
        description="the robot stopped, lost its link or left its running states during it: "
        "shown apart, left out of the statistics unless include_interrupted"
    )
    interruption: str | None = Field(
        description='what interrupted it, in words ("Emergency stop", "no frames for 3.2 s '
        '(link lost)", "left running: Standalone standby"); null: a whole cycle'
    )


class CycleStatistics(BaseModel):
    count: int = Field(
        ge=0,
        description="cycles that started in the range and the statistics are of (without the "
        "interrupted ones unless include_interrupted)",
    )
    interrupted: int = Field(ge=0, description="interrupted cycles that started in the range")
    include_interrupted: bool = Field(description="whether the statistics include them")
    last_s: float | None = Field(description="the newest cycle's duration, s")
    window: int = Field(ge=0, description="how many of the newest cycles mean/min/max are of")
    mean_s: float | None
    min_s: float | None
    max_s: float | None


class CycleTriggerInfo(BaseModel):
    text: str = Field(description="as the settings give it (cycle_trigger)")
    label: str = Field(
        description="in words, as the robot labels the element: 'rising edge of Register out 63'"
    )


class CyclePage(BaseModel):
    """A robot's cycles in a range (oldest first) and their statistics."""

    robot: str
    trigger: CycleTriggerInfo | None = Field(description="null: the robot has no cycle trigger")
    cycles: list[CycleRow] = Field(description="the newest `limit` of the range, oldest first")
    statistics: CycleStatistics
    in_progress_since: float | None = Field(
        description="when the cycle in progress started (s since the epoch); null: none"
    )

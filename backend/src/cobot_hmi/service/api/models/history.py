"""Layer: service. The API's contract: History answers (ranges, series, events, status)."""

from __future__ import annotations

from typing import Final, Literal

from pydantic import BaseModel, ConfigDict, Field

from cobot_hmi.service.api.models.events import Event
from cobot_hmi.service.api.models.stream import StreamMessage

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

"""Layer: service. The API's contract: The WebSocket stream's messages."""

from __future__ import annotations

from typing import Annotated, Final, Literal

from pydantic import BaseModel, Field, TypeAdapter

from cobot_hmi.layout import (
    LAYOUT_VERSION,
)
from cobot_hmi.service.api.models.events import Alarm, Event
from cobot_hmi.service.api.models.frames import Frame
from cobot_hmi.service.api.models.status import CellAlarmSummary, ConnectionStatus, ControlStatus

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
    time_zone: str = Field(
        default="UTC",
        description="the plant's time zone (the time_zone setting, an IANA name): the pages "
        "write every time in it",
    )
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

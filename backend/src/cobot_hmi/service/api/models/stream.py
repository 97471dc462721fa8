"""Layer: service. The API's contract: The WebSocket stream's messages."""

from __future__ import annotations

from typing import Annotated, Final, Literal

from pydantic import BaseModel, ConfigDict, Field, TypeAdapter

from cobot_hmi.layout import (
    LAYOUT_VERSION,
)
from cobot_hmi.service.api.models.events import Alarm, Event
from cobot_hmi.service.api.models.frames import Frame, SubscribedFrame
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
    frame: Frame | SubscribedFrame = Field(
        description="every field; after a `subscribed` answer naming fields, only those"
    )


class KioskConfig(BaseModel):
    """The kiosk's settings (docs/operations.md, "Kiosk"), for every page of the stream."""

    plot_window_s: float = Field(description="how far the kiosk's plots look back, s")
    shift_starts: list[str] = Field(
        description="when the plant's shifts start, HH:MM in the plant's time zone, sorted"
    )


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
    kiosk: KioskConfig | None = Field(
        default=None, description="the kiosk's settings (plot window, shifts)"
    )


class SubscribeMessage(BaseModel):
    """Sent by a client: what it shows, at the rate it draws. The frames after the service's
    `subscribed` answer carry only these fields (null: every field) at this rate (null: every
    frame). A page that shows a few numbers on a phone asks for those at its drawing rate."""

    model_config = ConfigDict(extra="forbid")

    type: Literal["subscribe"]
    fields: list[str] | None = Field(
        default=None,
        max_length=64,
        description="frame fields by their layout names (robot_state brings robot_state_name "
        "along); null: every field",
    )
    rate_hz: float | None = Field(
        default=None,
        gt=0,
        allow_inf_nan=False,
        description="frames per second at most (decimated as `?rate=`); null: every frame",
    )


class SubscribedMessage(BaseModel):
    """The service's answer to a `subscribe`: the frames after it are these."""

    type: Literal["subscribed"]
    fields: list[str] | None = Field(description="the fields the frames now carry, in layout order")
    rate_hz: float | None


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
    HelloMessage
    | FramesMessage
    | DroppedMessage
    | StatusMessage
    | EventMessage
    | SubscribedMessage,
    Field(discriminator="type"),
]
STREAM_MESSAGE: Final = TypeAdapter(StreamMessage)
"""Validates one WebSocket message (tests; never the hot path)."""
EVENT: Final = TypeAdapter(Event)
SUBSCRIBE_MESSAGE: Final = TypeAdapter(SubscribeMessage)
"""Validates a client's message (not a frame's path: a client sends a few)."""

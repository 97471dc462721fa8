"""Layer: service. The robots' streams and writes: how the service batches each robot's frames
to the pages' WebSockets and bounds a slow client, when a frame is stale, how often status
messages go out, how long a write waits for the robot's confirmation. The ``stream`` part of the
service's settings, given to each robot (``robots.robot.RobotRuntime``)."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict

from cobot_hmi.service.setting_fields import Milliseconds, Seconds, setting


class StreamSettings(BaseModel):
    """A robot's frames to the pages, and its writes' confirmation."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    write_timeout_ms: Milliseconds = setting(
        1000.0, "how long a write waits for the robot to confirm, ms"
    )
    stale_after_ms: Milliseconds = setting(500.0, "a frame older than this is flagged stale, ms")
    ws_batch_ms: Milliseconds = setting(50.0, "WebSocket broadcast period (frames per message), ms")
    ws_queue_frames: int = setting(400, "frames a WebSocket client may have queued", ge=1)
    ws_stall_timeout_s: Seconds = setting(
        5.0, "a client whose send is stuck this long is dropped, s"
    )
    status_interval_s: Seconds = setting(1.0, "period of WebSocket status messages, s")

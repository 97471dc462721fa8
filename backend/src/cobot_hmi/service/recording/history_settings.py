"""Layer: service. The history recorder's settings (every frame recorded; docs/operations.md
"History")."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict

from cobot_hmi.service.setting_fields import ExpandedPath, Seconds, setting


class HistorySettings(BaseModel):
    """Where and how long every frame is recorded."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    # --- history: every frame recorded (cobot_hmi.history; docs/operations.md "History")
    history: bool = setting(True, "record every frame of every robot (--no-history: off)")
    history_dir: ExpandedPath | None = setting(
        None, "directory of the recordings (default: STATE_DIR/history)"
    )
    history_retention_days: float = setting(
        7.0, "delete recordings older than this, days", gt=0, allow_inf_nan=False
    )
    history_retention_bytes: int = setting(
        5 * 1000**3, "keep the recordings under this size, bytes (oldest go first)", ge=1
    )
    history_segment_s: Seconds = setting(
        600.0, "a recording segment is closed (Parquet) after this long, s"
    )
    history_flush_s: float = setting(
        1.0, "frames reach the open segment's journal at least this often, s", gt=0, le=1.5
    )
    history_queue_frames: int = setting(
        6000, "frames per robot the recorder may fall behind by before it drops", ge=100
    )
    history_min_free_bytes: int = setting(
        256 * 1024**2, "recording pauses while the disk has less free space, bytes", ge=0
    )

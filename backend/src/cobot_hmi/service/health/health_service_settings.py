"""Layer: service (pure). The service's health settings, declared once (``setting_fields``):
whether every robot's health is read from its frames, how often, how often its state is saved
and a snapshot kept for the trends (docs/health.md "In the service"). The engine's own
thresholds are ``cobot_hmi.health.health_settings.HealthSettings``."""

from __future__ import annotations

from typing import Annotated

from pydantic import AfterValidator, BaseModel, ConfigDict

from cobot_hmi.arms import ARMS
from cobot_hmi.service.setting_fields import setting


def _check_arm(name: str) -> str:
    """Empty, or an arm of the arm table (``arms.py``), in its own spelling."""
    if not name:
        return name
    for arm in ARMS:
        if arm.name == name.strip().upper():
            return arm.name
    raise ValueError(f"unknown arm {name!r}; choose one of {', '.join(a.name for a in ARMS)}")


ArmName = Annotated[str, AfterValidator(_check_arm)]


class HealthServiceSettings(BaseModel):
    """Robot health in the service (one part of the settings, given to ``service.health``
    alone)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    health_enabled: bool = setting(
        True, "read every robot's health from its frames (--no-health-enabled: off)"
    )
    health_refresh_s: float = setting(
        5.0,
        "frames reach the health engine in blocks this often, s (a block's fixed cost is most "
        "of a one-second block's: bench/health --engine-only, 3.8 µs a frame in 1 s blocks, "
        "1.7 µs in 5 s blocks; a verdict is advice on wear of weeks)",
        gt=0,
        le=10.0,
        allow_inf_nan=False,
    )
    health_report_s: float = setting(
        30.0,
        "the verdicts are judged again this often (advisory alarms, health events), s (a "
        "report takes tens of milliseconds: often enough for advice on wear of weeks)",
        gt=0,
        le=600.0,
        allow_inf_nan=False,
    )
    health_save_s: float = setting(
        60.0,
        "each robot's health state (life used, knocks, baselines) is saved this often, s, and "
        "when the service stops",
        gt=0,
        le=3600.0,
        allow_inf_nan=False,
    )
    health_snapshot_s: float = setting(
        600.0,
        "a snapshot of each robot's figures is kept this often for the trends and the "
        "weekly report, s",
        gt=0,
        le=86_400.0,
        allow_inf_nan=False,
    )
    health_queue_frames: int = setting(
        6000,
        "frames per robot health may fall behind by before the oldest are dropped (counted)",
        ge=100,
    )
    health_arm: ArmName = setting(
        "",
        "the arm model of every robot whose identity names none (M1013, M0609; empty: from "
        "the identity's product name, else M1013)",
    )

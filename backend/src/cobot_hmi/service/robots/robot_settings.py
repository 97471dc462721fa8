"""Layer: service. One robot of the cell and its class 1 connection (a ``[[robots]]`` table)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from pydantic import BaseModel, ConfigDict, Field

from cobot_hmi import connection_params as cp
from cobot_hmi.service.robots.cycle_settings import CycleSettings
from cobot_hmi.service.setting_fields import (
    Port,
    RobotMode,
    RobotName,
    connection_setting,
    rpi_ms_setting,
    setting,
)

if TYPE_CHECKING:
    from cobot_hmi.scanner.originator import OriginatorSettings


# --------------------------------------------------------------------------- one robot


class RobotSettings(CycleSettings, BaseModel):  # cycle timing (issue 23)
    """One robot of the cell and its class 1 connection (a ``[[robots]]`` table)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    name: RobotName = Field(
        description="the robot's name in the API and the UI: lower-case letters, digits, _ and -"
    )
    host: str = Field(min_length=1, description="robot (target) address")
    tcp_port: Port = connection_setting(cp.ENIP_TCP_PORT)
    mode: RobotMode = setting(
        "exclusive-owner",
        "exclusive-owner (the service may write) or input-only (read-only, never owns outputs)",
    )
    rpi_ms: float = rpi_ms_setting()
    timeout_multiplier: int = connection_setting(cp.TIMEOUT_MULTIPLIER)
    config_instance: int = connection_setting(cp.CONFIG_INSTANCE)
    o2t_instance: int = connection_setting(cp.O2T_INSTANCE)
    t2o_instance: int = connection_setting(cp.T2O_INSTANCE)
    heartbeat_instance: int = connection_setting(cp.HEARTBEAT_INSTANCE)
    o2t_size: int = connection_setting(cp.O2T_SIZE)
    t2o_size: int = connection_setting(cp.T2O_SIZE)
    large_forward_open: bool = setting(False, "use Large Forward Open (0x5B)")

    @property
    def input_only(self) -> bool:
        return self.mode == "input-only"

    @property
    def rpi_us(self) -> int:
        return round(self.rpi_ms * 1000)

    def originator_settings(
        self, local_host: str | None, udp_port: int, *, request_t2o_port: int | None = None
    ) -> OriginatorSettings:
        """The scanner's settings for this robot's class 1 connection."""
        from cobot_hmi.scanner.originator import OriginatorSettings

        return OriginatorSettings(
            robot_host=self.host,
            tcp_port=self.tcp_port,
            local_host=local_host,
            local_udp_port=udp_port,
            rpi_us=self.rpi_us,
            timeout_multiplier=self.timeout_multiplier,
            input_only=self.input_only,
            large_forward_open=self.large_forward_open,
            config_instance=self.config_instance,
            o2t_instance=self.o2t_instance,
            t2o_instance=self.t2o_instance,
            heartbeat_instance=self.heartbeat_instance,
            o2t_size=self.o2t_size,
            t2o_size=self.t2o_size,
            request_t2o_port=request_t2o_port,
        )

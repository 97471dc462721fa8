"""Layer: service. The robot cell's settings, one part of the service's (``cell``): which robots
there are and the connection settings every robot inherits unless its own ``[[robots]]`` table
says otherwise, the service's end of the class 1 connections, when a robot down too long
makes the service unhealthy.

Robots: ``[[robots]]`` tables in the TOML file (or ``COBOT_HMI_ROBOTS`` as a JSON list) name
any number of robots, each a ``RobotSettings``; ``--robot HOST [--robot-name NAME]`` (or
``COBOT_HMI_ROBOT_HOST``) is the one-robot shortcut. The connection settings here (``rpi_ms``,
``timeout_multiplier``, instances, sizes, ``input_only``, ``cycle_trigger`` …) are the
defaults of every robot that does not set its own; ``robots`` holds them resolved.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Final

from pydantic import ConfigDict, Field, model_validator

from cobot_hmi import connection_params as cp
from cobot_hmi.service.robots.cycle_settings import CycleSettings
from cobot_hmi.service.robots.robot_settings import RobotSettings
from cobot_hmi.service.setting_fields import (
    DEFAULT_ROBOT_NAME,
    Port,
    RobotName,
    Seconds,
    SettingsError,
    connection_setting,
    rpi_ms_setting,
    setting,
)

if TYPE_CHECKING:
    from cobot_hmi.scanner.originator import OriginatorSettings

_INHERITED: Final = {
    # robot setting: the cell's setting that is its default
    "tcp_port": "robot_tcp_port",
    "rpi_ms": "rpi_ms",
    "timeout_multiplier": "timeout_multiplier",
    "config_instance": "config_instance",
    "o2t_instance": "o2t_instance",
    "t2o_instance": "t2o_instance",
    "heartbeat_instance": "heartbeat_instance",
    "o2t_size": "o2t_size",
    "t2o_size": "t2o_size",
    "large_forward_open": "large_forward_open",
    "cycle_trigger": "cycle_trigger",  # cycle timing (issue 23)
}


class CellSettings(CycleSettings):  # its cycle_trigger: every robot's default (issue 23)
    """The robots and every robot's connection defaults (docs/operations.md, "Settings")."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    # --- the robots
    robots: list[RobotSettings] = Field(
        default_factory=list,
        description="the robots ([[robots]] tables; COBOT_HMI_ROBOTS as a JSON list)",
    )
    robot_host: str = setting("", "one robot's address (the one-robot shortcut)", flag="--robot")
    robot_name: RobotName = setting(
        DEFAULT_ROBOT_NAME, "that robot's name in the API (with --robot)"
    )
    # --- every robot's connection, unless its [[robots]] table says otherwise
    robot_tcp_port: Port = connection_setting(cp.ENIP_TCP_PORT)
    rpi_ms: float = rpi_ms_setting()
    timeout_multiplier: int = connection_setting(cp.TIMEOUT_MULTIPLIER)
    input_only: bool = setting(
        False, "read-only: input-only connections, never owning outputs (robots' mode)"
    )
    large_forward_open: bool = setting(False, "use Large Forward Open (0x5B)")
    config_instance: int = connection_setting(cp.CONFIG_INSTANCE)
    o2t_instance: int = connection_setting(cp.O2T_INSTANCE)
    t2o_instance: int = connection_setting(cp.T2O_INSTANCE)
    heartbeat_instance: int = connection_setting(cp.HEARTBEAT_INSTANCE)
    o2t_size: int = connection_setting(cp.O2T_SIZE)
    t2o_size: int = connection_setting(cp.T2O_SIZE)
    # --- the service's end of the class 1 connections (one UDP socket for every robot)
    local_host: str = setting("0.0.0.0", "local address receiving T→O (UDP)")
    local_udp_port: Port = connection_setting(cp.CLASS1_UDP_PORT)
    request_t2o_port: Port | None = setting(
        None, "ask every robot to send T→O to this local UDP port (bound instead of 2222)", ge=1
    )
    cyclic_niceness: int = setting(
        0,
        "nice value of the cyclic I/O thread; below 0 raises its priority (CAP_SYS_NICE)",
        ge=-20,
        le=19,
    )
    link_down_unhealthy_s: Seconds = setting(
        30.0, "/healthz fails when a robot has not been connected for this long, s"
    )

    @model_validator(mode="after")
    def _resolve_robots(self) -> CellSettings:
        """Fill each robot's unset connection settings from the cell's; the shortcut."""
        # Idempotent: the resolved list keeps each robot's own fields set and no other.
        given = self.robots if "robots" in self.model_fields_set else []
        if given and self.robot_host:
            raise ValueError(
                "give either one robot (robot_host, --robot) or a robot list ([[robots]]), not both"
            )
        inherited: dict[str, object] = {key: getattr(self, top) for key, top in _INHERITED.items()}
        inherited["mode"] = "input-only" if self.input_only else "exclusive-owner"
        if given:
            robots = [
                RobotSettings.model_construct(
                    _fields_set=robot.model_fields_set,
                    **{
                        **{k: v for k, v in inherited.items() if k not in robot.model_fields_set},
                        **{k: getattr(robot, k) for k in robot.model_fields_set},
                    },
                )
                for robot in given
            ]
        elif self.robot_host:
            robots = [RobotSettings(name=self.robot_name, host=self.robot_host, **inherited)]  # type: ignore[arg-type]
        else:
            robots = []
        _check_distinct(robots)
        # The resolved list replaces the given one (the model is frozen; this is its making).
        self.__dict__["robots"] = robots
        return self

    # ------------------------------------------------------------ derived

    def require_robots(self) -> list[RobotSettings]:
        """The robots, or ``SettingsError`` when none is given (``serve`` needs one)."""
        if not self.robots:
            raise SettingsError(
                "robot_host: no robot given (--robot HOST, COBOT_HMI_ROBOT_HOST, or [[robots]] "
                "tables in the TOML file)"
            )
        return self.robots

    @property
    def default_robot(self) -> RobotSettings:
        """The first robot: the one the deprecated single-robot API paths answer for."""
        return self.require_robots()[0]

    @property
    def rpi_us(self) -> int:
        return round(self.rpi_ms * 1000)

    @property
    def t2o_udp_port(self) -> int:
        """The local UDP port every robot's T→O comes to."""
        return self.request_t2o_port if self.request_t2o_port is not None else self.local_udp_port

    def originator_settings(self, robot: RobotSettings | None = None) -> OriginatorSettings:
        """The scanner's settings for ``robot``'s connection (default: the first robot)."""
        robot = robot if robot is not None else self.default_robot
        return robot.originator_settings(
            self.local_host, self.local_udp_port, request_t2o_port=self.request_t2o_port
        )


def _check_distinct(robots: list[RobotSettings]) -> None:
    """No name twice, no two robots at one address."""
    seen: set[str] = set()
    addresses: dict[tuple[str, int], str] = {}
    for robot in robots:
        if robot.name in seen:
            raise ValueError(f"robots: the name {robot.name!r} is given twice")
        seen.add(robot.name)
        address = (robot.host, robot.tcp_port)
        if address in addresses:
            raise ValueError(
                f"robots: {addresses[address]!r} and {robot.name!r} are both "
                f"{robot.host}:{robot.tcp_port}"
            )
        addresses[address] = robot.name

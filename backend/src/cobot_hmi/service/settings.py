"""Layer: service. The one settings object of the backend service, composed of each concern's.

``ServiceSettings`` is a pydantic-settings model whose fields come from the settings of each
concern, each in its own room: the robots' connections (here and ``robots.settings``), the web
service and its limits (``web.settings``, ``web.tls_settings``), directory login
(``access.directory_settings``), alarms (``alarms.settings``), history
(``recording.settings``), cycle timing (``robots.cycle_settings``), the kiosk
(``kiosk.settings``) and robot health (``health.settings``). The doors above the service
(the Sparkplug B edge node, the OPC UA server) add theirs in ``cobot_hmi.settings.HmiSettings``,
the settings of ``cobot-hmi serve``: the service imports neither. Keys stay flat: a field's
name is its TOML key, ``COBOT_HMI_<NAME>`` its environment variable and ``--name`` its flag
(``setting_fields`` declares them; ``config.loading`` layers defaults < TOML < environment <
flags; ``config.arguments`` derives the command line). Constructing ``ServiceSettings(...)``
directly reads nothing but its arguments (tests, the demo).

Robots: ``[[robots]]`` tables in the TOML file (or ``COBOT_HMI_ROBOTS`` as a JSON list) name
any number of robots, each a ``RobotSettings``; ``--robot HOST [--robot-name NAME]`` (or
``COBOT_HMI_ROBOT_HOST``) is the one-robot shortcut. The robot list comes whole from the
highest source that gives one (a ``--robot`` flag replaces the file's ``[[robots]]``). The
top-level connection settings (``rpi_ms``, ``timeout_multiplier``, instances, sizes,
``input_only`` …) are the defaults of every robot that does not set its own.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Final, Self

from pydantic import Field, model_validator
from pydantic_settings import BaseSettings, PydanticBaseSettingsSource, SettingsConfigDict

from cobot_hmi import connection_params as cp
from cobot_hmi.service.access.directory_settings import DirectorySettings
from cobot_hmi.service.alarms.settings import AlarmLimitSettings, AlarmSettings
from cobot_hmi.service.health.settings import HealthServiceSettings
from cobot_hmi.service.kiosk.settings import KioskSettings
from cobot_hmi.service.recording.settings import HistorySettings
from cobot_hmi.service.robots.cycle_settings import CycleSettings
from cobot_hmi.service.robots.settings import RobotSettings
from cobot_hmi.service.setting_fields import (
    DEFAULT_DEADBANDS,
    DEFAULT_ROBOT_NAME,
    ENV_PREFIX,
    Port,
    RobotName,
    Seconds,
    SettingsError,
    TimeZoneName,
    connection_setting,
    rpi_ms_setting,
    setting,
)
from cobot_hmi.service.web.settings import WebSettings
from cobot_hmi.service.web.tls_settings import TlsSettings

if TYPE_CHECKING:
    from cobot_hmi.scanner.originator import OriginatorSettings

__all__ = [
    "DEFAULT_DEADBANDS",
    "AlarmSettings",
    "RobotSettings",
    "ServiceSettings",
    "SettingsError",
]
"""Names other modules import from here (each defined in its concern's module)."""


_INHERITED: Final = {
    # robot setting: the top-level setting that is its default
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


# --------------------------------------------------------------------------- the service


class ServiceSettings(  # each concern's fields; flags and TOML keys list the last base's first
    HealthServiceSettings,
    KioskSettings,
    CycleSettings,
    HistorySettings,
    AlarmLimitSettings,
    DirectorySettings,
    TlsSettings,
    WebSettings,
    BaseSettings,
):
    """Everything the service itself can be told (``cobot_hmi.settings.HmiSettings`` adds the
    doors above it: Sparkplug B and OPC UA). Field names are the TOML keys."""

    model_config = SettingsConfigDict(
        env_prefix=ENV_PREFIX, extra="forbid", frozen=True, case_sensitive=False
    )

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
    time_zone: TimeZoneName = setting(
        "",
        "the plant's time zone, an IANA name (Europe/Berlin): every time the pages, the CSV "
        "exports and the prints show is in it; empty: the service host's zone",
    )

    @classmethod
    def settings_customise_sources(
        cls,
        settings_cls: type[BaseSettings],
        init_settings: PydanticBaseSettingsSource,
        env_settings: PydanticBaseSettingsSource,
        dotenv_settings: PydanticBaseSettingsSource,
        file_secret_settings: PydanticBaseSettingsSource,
    ) -> tuple[PydanticBaseSettingsSource, ...]:
        # Only the arguments: ``load_settings`` layers flags, environment and TOML itself, so
        # that the robot list comes whole from one source and errors name their source.
        return (init_settings,)

    @model_validator(mode="after")
    def _resolve_robots(self) -> ServiceSettings:
        """Fill each robot's unset connection settings from the top level; the shortcut."""
        # Idempotent: pydantic runs this twice for a settings class (once inside __init__).
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
        seen: dict[str, RobotSettings] = {}
        addresses: dict[tuple[str, int], str] = {}
        for robot in robots:
            if robot.name in seen:
                raise ValueError(f"robots: the name {robot.name!r} is given twice")
            seen[robot.name] = robot
            address = (robot.host, robot.tcp_port)
            if address in addresses:
                raise ValueError(
                    f"robots: {addresses[address]!r} and {robot.name!r} are both "
                    f"{robot.host}:{robot.tcp_port}"
                )
            addresses[address] = robot.name
        # The resolved list replaces the given one (the model is frozen; this is its making).
        self.__dict__["robots"] = robots
        alarm_names: set[str] = set()
        for alarm in self.alarms:
            if alarm.robot is not None and robots and alarm.robot not in seen:
                raise ValueError(
                    f"alarms: {alarm.name!r} names the robot {alarm.robot!r}; "
                    f"known: {', '.join(seen)}"
                )
            if alarm.name in alarm_names:
                raise ValueError(f"alarms: the name {alarm.name!r} is given twice")
            alarm_names.add(alarm.name)
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
    def users_path(self) -> Path:
        return self.users_file if self.users_file is not None else self.state_dir / "users.json"

    @property
    def database_path(self) -> Path:
        return self.database if self.database is not None else self.state_dir / "hmi.db"

    @property
    def history_path(self) -> Path:
        return self.history_dir if self.history_dir is not None else self.state_dir / "history"

    @property
    def frontend_path(self) -> Path:
        if self.frontend_dir is not None:
            return self.frontend_dir
        # backend/src/cobot_hmi/service/settings.py → the repository's frontend/dist
        return Path(__file__).resolve().parents[4] / "frontend" / "dist"

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

    def replace(self, **changes: object) -> Self:
        """A copy with ``changes``, checked again (robots re-inherit the new defaults)."""
        given: dict[str, object] = {name: getattr(self, name) for name in self.model_fields_set}
        if changes.get("robots"):
            given.pop("robot_host", None)
        if changes.get("robot_host"):
            given.pop("robots", None)
        return type(self).model_validate({**given, **changes})

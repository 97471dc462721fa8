"""Layer: service. The one settings object of the backend service and how it is loaded.

``ServiceSettings`` is a pydantic-settings model. Precedence, highest first: command-line
flags, environment variables ``COBOT_HMI_<NAME>`` (``COBOT_HMI_RPI_MS=4``), an optional TOML
file (``--config FILE`` or ``COBOT_HMI_CONFIG``) whose top-level keys are the field names
below, then the defaults. ``load_settings`` layers them; constructing ``ServiceSettings(...)``
directly reads nothing but its arguments (tests, the demo).

Robots: ``[[robots]]`` tables in the TOML file (or ``COBOT_HMI_ROBOTS`` as a JSON list) name
any number of robots, each a ``RobotSettings``; ``--robot HOST [--robot-name NAME]`` (or
``COBOT_HMI_ROBOT_HOST``) is the one-robot shortcut. The robot list comes whole from the
highest source that gives one (a ``--robot`` flag replaces the file's ``[[robots]]``). The
top-level connection settings (``rpi_ms``, ``timeout_multiplier``, instances, sizes,
``input_only`` …) are the defaults of every robot that does not set its own.

Declaring a setting: one field, ``name: type = setting(default, "help", bounds…)``; its flag
(``--name``, or ``flag=``) and environment variable (``COBOT_HMI_NAME``) are derived. Connection
settings take default, bounds and help from ``cobot_hmi.connection_params``, shared with the
emulator and the scanner. Pure: no sockets; imports nothing of the project except the
connection declarations and (lazily) the scanner's settings type and the layout (whose units
and field names key the Sparkplug deadbands).
"""

from __future__ import annotations

import argparse
import ipaddress
import os
import tomllib
import types
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Final, Literal

from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    ValidationError,
    model_validator,
)
from pydantic_settings import (
    BaseSettings,
    EnvSettingsSource,
    NoDecode,
    PydanticBaseSettingsSource,
    SettingsConfigDict,
    TomlConfigSettingsSource,
)
from pydantic_settings import SettingsError as PydanticSettingsError
from pydantic_settings.sources.utils import parse_env_vars

from cobot_hmi import connection_params as cp
from cobot_hmi.opcua.settings import OpcUaSettings  # OPC UA (issue 22): its opcua_* fields
from cobot_hmi.service.access.directory_settings import DirectorySettings  # issue 25: ldap_*
from cobot_hmi.service.api.tls_settings import TlsSettings  # issue 25: tls_*, HTTPS
from cobot_hmi.service.cycles.settings import CycleSettings  # cycle timing (issue 23)

if TYPE_CHECKING:
    from cobot_hmi.scanner.originator import OriginatorSettings

O2T_SIZE: Final = cp.O2T_SIZE.default
T2O_SIZE: Final = cp.T2O_SIZE.default
ENV_PREFIX: Final = "COBOT_HMI_"
CONFIG_ENV: Final = "COBOT_HMI_CONFIG"
ROBOT_NAME_PATTERN: Final = r"^[a-z0-9][a-z0-9_-]{0,31}$"
DEFAULT_ROBOT_NAME: Final = "robot"
RobotMode = Literal["exclusive-owner", "input-only"]


class SettingsError(ValueError):
    """A setting that cannot be parsed or is out of range; the message names it and its source."""


# --------------------------------------------------------------------------- declaring


def setting(default: Any, help_text: str, *, flag: str | None = None, **bounds: Any) -> Any:
    """One setting's declaration: default, help, bounds (``ge=``, ``le=``, ``gt=``, ``pattern=``).

    The flag is ``--name-with-dashes`` unless ``flag`` is given; the environment variable is
    ``COBOT_HMI_NAME``.
    """
    extra: dict[str, Any] | None = {"flag": flag} if flag else None
    return Field(default, description=help_text, json_schema_extra=extra, **bounds)


def connection_setting(param: cp.ConnectionParam[int], *, flag: str | None = None) -> Any:
    """A setting from the shared connection declaration (``cobot_hmi.connection_params``)."""
    unit = f", {param.unit}" if param.unit else ""
    return setting(param.default, param.help + unit, flag=flag, ge=param.minimum, le=param.maximum)


def rpi_ms_setting() -> Any:
    """The RPI in milliseconds (the declaration is in µs: ``connection_params.RPI_US``)."""
    param = cp.RPI_US
    return setting(
        param.default / 1000,
        param.help + ", ms",
        ge=param.minimum / 1000,
        le=param.maximum / 1000,
        allow_inf_nan=False,
    )


def _split_commas(value: object) -> object:
    if isinstance(value, str):
        return [part.strip() for part in value.split(",") if part.strip()]
    return value


CommaList = Annotated[list[str], NoDecode, BeforeValidator(_split_commas)]
"""A list setting written ``a,b,c`` in a flag or variable (a list in TOML)."""


def _check_proxies(entries: list[str]) -> list[str]:
    """Each entry an IP address or a network (``ipaddress``), in its canonical form.

    uvicorn takes any entry it cannot parse as a literal host name that no peer address ever
    equals, so a typo (``10.0.0.300``, ``10.0.0.1/24`` with host bits set) would silently trust
    nobody; refused here, the service does not start and the message names the entry. ``*``
    (uvicorn's "trust every peer") is refused too: whoever can reach the port could then
    choose the client address the login throttle and the audit trail see.
    """
    checked = []
    for entry in entries:
        try:
            if "/" in entry:
                checked.append(str(ipaddress.ip_network(entry)))
            else:
                checked.append(str(ipaddress.ip_address(entry)))
        except ValueError as error:
            hint = (
                "trusting every peer is not offered: name the proxies"
                if entry == "*"
                else f"not an IP address or network ({error})"
            )
            raise ValueError(f"entry {entry!r}: {hint}") from None
    return checked


ProxyList = Annotated[CommaList, AfterValidator(_check_proxies)]
"""Addresses and networks, ``a,b/24`` in a flag or variable; canonical, each one checked."""
ExpandedPath = Annotated[Path, AfterValidator(Path.expanduser)]


def _readable_file(path: Path) -> Path:
    path = path.expanduser()
    if not path.is_file() or not os.access(path, os.R_OK):
        raise ValueError(f"{path} is not a readable file")
    return path


ReadableFile = Annotated[Path, AfterValidator(_readable_file)]
"""A file that must be there when the service starts (a certificate, a key)."""
Seconds = Annotated[float, Field(gt=0, allow_inf_nan=False)]
Milliseconds = Annotated[float, Field(gt=0, allow_inf_nan=False)]
Port = Annotated[int, Field(ge=0, le=65535)]
"""A TCP or UDP port; 0 asks the OS for any free one (the HTTP port in tests)."""
RobotName = Annotated[str, Field(pattern=ROBOT_NAME_PATTERN)]
SPARKPLUG_ID_PATTERN: Final = r"^[^+#/]+$"
"""A Sparkplug group, edge node or device id: no MQTT wildcard, no topic level separator."""
SparkplugId = Annotated[str, Field(pattern=SPARKPLUG_ID_PATTERN)]
DEFAULT_DEADBANDS: Final = {
    # The layout's units (cobot_hmi.layout): about the last digit a display of each one shows.
    "degree": 0.01,
    "degree/s": 0.1,
    "A": 0.01,
    "°C": 0.1,
    "N·m": 0.05,
    "mm": 0.1,
    "mm/s": 0.5,
    "N": 0.5,
    "mA or V per its type": 0.01,
}
"""Sparkplug report-by-exception deadbands by unit (absolute, in that unit)."""


def _parse_deadbands(value: object) -> object:
    """``unit=value,field=value`` (a flag or variable) to a mapping; a TOML table passes."""
    if not isinstance(value, str):
        return value
    pairs: dict[str, str] = {}
    for part in value.split(","):
        if not part.strip():
            continue
        key, sep, number = part.partition("=")
        if not sep:
            raise ValueError(f"expected UNIT=VALUE or FIELD=VALUE, got {part.strip()!r}")
        pairs[key.strip()] = number.strip()
    return pairs


def _check_deadbands(value: dict[str, float]) -> dict[str, float]:
    """Keys are the layout's units or T→O field names; the defaults fill the other units."""
    from cobot_hmi.layout import T2O_FIELDS

    known = {f.unit for f in T2O_FIELDS if f.unit} | {f.name for f in T2O_FIELDS}
    for key, number in value.items():
        if key not in known:
            units = ", ".join(sorted({f.unit for f in T2O_FIELDS if f.unit}))
            raise ValueError(f"{key!r} is neither a unit ({units}) nor a T→O field name")
        if number < 0:
            raise ValueError(f"{key}: a deadband is not negative, got {number}")
    return {**DEFAULT_DEADBANDS, **value}


Deadbands = Annotated[
    dict[str, Annotated[float, Field(allow_inf_nan=False)]],
    NoDecode,
    BeforeValidator(_parse_deadbands),
    AfterValidator(_check_deadbands),
]


def _default_state_dir() -> Path:
    base = os.environ.get("XDG_STATE_HOME") or str(Path.home() / ".local" / "state")
    return Path(base) / "cobot-hmi"


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


# --------------------------------------------------------------------------- alarms

ALARM_NAME_PATTERN: Final = r"^[a-z0-9][a-z0-9_-]{0,47}$"
AlarmPriority = Literal["critical", "high", "medium", "low"]


class AlarmSettings(BaseModel):
    """A user-defined alarm on one element of the robot's T→O frame (an ``[[alarms]]`` table):
    a number above ``high`` or below ``low`` (with ``deadband``), or a bit equal to
    ``active_when``; ``on_delay_s`` / ``off_delay_s`` before it comes / clears
    (docs/operations.md "Alarms")."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    name: str = Field(
        pattern=ALARM_NAME_PATTERN,
        description="the alarm's key (user.NAME in the API): lower-case letters, digits, _ and -",
    )
    field: str = Field(description="a T→O field of the layout (joint_motor_current, tool_di…)")
    index: int | None = Field(
        default=None,
        ge=0,
        description="the element's 0-based index in the frame's array (controlbox_di index 2 "
        "is DI 3); none for a scalar field",
    )
    robot: RobotName | None = Field(default=None, description="one robot (default: every robot)")
    high: float | None = Field(default=None, allow_inf_nan=False, description="above: active")
    low: float | None = Field(default=None, allow_inf_nan=False, description="below: active")
    active_when: bool | None = Field(default=None, description="a bit: the value that alarms")
    deadband: float = Field(default=0.0, ge=0, allow_inf_nan=False, description="hysteresis")
    on_delay_s: float = Field(default=0.0, ge=0, le=3600, allow_inf_nan=False)
    off_delay_s: float = Field(default=0.0, ge=0, le=3600, allow_inf_nan=False)
    priority: AlarmPriority = "medium"
    message: str = Field(default="", max_length=200, description="the alarm's name in words")

    @model_validator(mode="after")
    def _check_element(self) -> AlarmSettings:
        from cobot_hmi.layout import T2O_FIELDS

        fields = {f.name: f for f in T2O_FIELDS}
        f = fields.get(self.field)
        if f is None:
            raise ValueError(f"{self.field!r} is not a T→O field ({', '.join(fields)})")
        if f.element_names:
            raise ValueError(f"{self.field} is a record, not a number or a bit")
        single = f.scalar or f.count == 1
        if self.index is None and not single:
            raise ValueError(f"{self.field} has {f.count} elements: give index 0–{f.count - 1}")
        if self.index is not None and self.index >= f.count:
            raise ValueError(f"{self.field}: index {self.index} is not in 0–{f.count - 1}")
        if f.value_kind == "bool":
            if self.high is not None or self.low is not None or self.deadband:
                raise ValueError(f"{self.field} is a bit: give active_when, not high/low")
        else:
            if self.active_when is not None:
                raise ValueError(f"{self.field} is a number: give high and/or low")
            if self.high is None and self.low is None:
                raise ValueError(f"{self.field}: give high and/or low")
            if self.high is not None and self.low is not None and self.low >= self.high:
                raise ValueError(f"low ({self.low:g}) must be below high ({self.high:g})")
        return self


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


class ServiceSettings(  # OPC UA (22), cycles (23), directory login (25)
    TlsSettings, DirectorySettings, OpcUaSettings, CycleSettings, BaseSettings
):
    """Everything ``cobot-hmi serve`` can be told. Field names are the TOML keys."""

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
    # --- the web service
    host: str = setting("127.0.0.1", "HTTP bind address")
    port: Port = setting(8000, "HTTP port")
    state_dir: ExpandedPath = Field(
        default_factory=_default_state_dir,
        description="directory for the users file and database",
    )
    users_file: ExpandedPath | None = setting(None, "users file (default: STATE_DIR/users.json)")
    database: ExpandedPath | None = setting(
        None, "SQLite audit/event database (default: STATE_DIR/hmi.db)"
    )
    frontend_dir: ExpandedPath | None = setting(
        None, "built frontend to serve at / (default: frontend/dist)"
    )
    view_requires_login: bool = setting(False, "reading the API also needs a login")
    session_ttl_s: Seconds = setting(8 * 3600.0, "a session expires after this long unused, s")
    cookie_secure: bool = setting(False, "mark the session cookie Secure (behind HTTPS)")
    login_free_attempts: int = setting(3, "failed logins allowed before slowing down", ge=0)
    login_delay_max_s: float = setting(
        30.0, "longest wait imposed after failed logins, s", ge=0, allow_inf_nan=False
    )
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
    # --- security (service/api/security.py and http_limits.py; docs/operations.md "Security")
    max_body_bytes: int = setting(64 * 1024, "largest request body, bytes (413 above)", ge=1024)
    allowed_hosts: CommaList = setting(
        [],
        "Host names served, comma-separated ('*.example.org' patterns, 'ip' for any IP "
        "literal, '*' for any); default: IP literals, localhost and this machine's name",
    )
    allowed_origins: CommaList = setting(
        [],
        "other origins (scheme://host:port) whose pages may write and stream, "
        "comma-separated; the service's own origin always may",
    )
    trusted_proxies: ProxyList = setting(
        [],
        "reverse proxies (addresses or networks) whose X-Forwarded-For/-Proto are "
        "believed, comma-separated; none by default",
    )
    login_user_delay_max_s: float = setting(
        4.0,
        "longest wait a user name's failed logins impose on other addresses, s",
        ge=0,
        allow_inf_nan=False,
    )
    anonymous_writes_per_s: float = setting(
        1.0, "refused writes without login allowed per client address, per s", gt=0
    )
    anonymous_write_burst: int = setting(
        20, "refused writes without login a client address may send at once", ge=1
    )
    http_max_connections: int = setting(
        512, "HTTP and WebSocket connections held at once (idle ones give way)", ge=8
    )
    http_idle_timeout_s: Seconds = setting(
        10.0, "a connection must send a request head, and then its body, within this each, s"
    )
    http_keep_alive_s: Seconds = setting(5.0, "an idle keep-alive connection is closed after, s")
    http_backlog: int = setting(2048, "pending TCP connections the kernel queues", ge=1)
    http_max_header_bytes: int = setting(
        16 * 1024, "largest request line and headers, bytes", ge=1024
    )
    # --- Sparkplug B edge node over MQTT (cobot_hmi.sparkplug; docs/operations.md "Sparkplug")
    mqtt_url: str = setting(
        "",
        "MQTT broker: mqtt://HOST:PORT or mqtts://HOST:PORT (TLS); empty: no Sparkplug",
        pattern=r"^$|^mqtts?://[^/:]+(:\d+)?/?$",
    )
    mqtt_user: str = setting("", "MQTT user name (empty: none)")
    mqtt_password: str = setting("", "MQTT password (prefer COBOT_HMI_MQTT_PASSWORD)")
    mqtt_ca_file: ReadableFile | None = setting(
        None, "CA certificates for mqtts:// (default: the system's)"
    )
    mqtt_client_cert: ReadableFile | None = setting(None, "client certificate (PEM) for mqtts://")
    mqtt_client_key: ReadableFile | None = setting(None, "its private key (PEM)")
    mqtt_writes: bool = setting(
        False, "accept DCMD writes over MQTT (through the write pipeline, with control)"
    )
    sparkplug_group: SparkplugId = setting("cobot-hmi", "Sparkplug group id")
    sparkplug_node: str = setting(
        "",
        "Sparkplug edge node id (default: this machine's host name)",
        pattern=r"^$|" + SPARKPLUG_ID_PATTERN,
    )
    sparkplug_primary_host: str = setting(
        "",
        "wait for this Sparkplug primary host application's STATE before births (empty: don't)",
        pattern=r"^$|" + SPARKPLUG_ID_PATTERN,
    )
    sparkplug_deadbands: Deadbands = setting(
        DEFAULT_DEADBANDS,
        "report-by-exception deadbands, UNIT=VALUE or FIELD=VALUE comma-separated (absolute, "
        "in the field's unit); unnamed units keep their defaults",
    )
    sparkplug_max_rate_hz: float = setting(
        10.0, "most DDATA messages per robot per second", gt=0, le=1000, allow_inf_nan=False
    )
    sparkplug_buffer_bytes: int = setting(
        64 * 1024 * 1024, "data kept on disk while the broker is away, bytes (0: none)", ge=0
    )
    # --- alarms (service/alarms; docs/operations.md "Alarms")
    alarms: list[AlarmSettings] = Field(
        default_factory=list,
        description="user-defined alarms ([[alarms]] tables; COBOT_HMI_ALARMS as a JSON list)",
    )
    alarm_motor_temperature_c: float = setting(
        80.0, "motor temperature alarm of each joint above this, °C", allow_inf_nan=False
    )
    alarm_motor_temperature_deadband_c: float = setting(
        2.0, "it clears this far below, °C", ge=0, allow_inf_nan=False
    )
    alarm_gap_rate_per_min: float = setting(
        10.0, "packet loss alarm: more T→O sequence gaps than this in a minute", ge=0
    )
    alarm_connection_delay_s: float = setting(
        2.0, "connection lost or stale this long raises its alarm, s", ge=0, le=3600
    )
    alarm_shelve_max_s: Seconds = setting(8 * 3600.0, "longest an alarm may be shelved, s")
    alarm_consequence_window_s: float = setting(
        5.0,
        "an alarm coming this long after its cause cleared (or while the cause is active) is its "
        "consequence, suppressed by design (SAFE_OFF after an e-stop's reset), s",
        ge=0,
        le=600,
        allow_inf_nan=False,
    )
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
    def sparkplug_node_id(self) -> str:
        """The edge node id: the setting, else the host name (``+ # /`` made ``_``)."""
        if self.sparkplug_node:
            return self.sparkplug_node
        import socket

        name = socket.gethostname() or "cobot-hmi"
        return name.replace("+", "_").replace("#", "_").replace("/", "_")

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

    def replace(self, **changes: object) -> ServiceSettings:
        """A copy with ``changes``, checked again (robots re-inherit the new defaults)."""
        given: dict[str, object] = {name: getattr(self, name) for name in self.model_fields_set}
        if changes.get("robots"):
            given.pop("robot_host", None)
        if changes.get("robot_host"):
            given.pop("robots", None)
        return type(self).model_validate({**given, **changes})


# --------------------------------------------------------------------------- loading

_ROBOT_GROUP: Final = ("robots", "robot_host")
"""Settings that together say which robots there are: taken from one source only."""


def env_name(name: str) -> str:
    return ENV_PREFIX + name.upper()


class _EnvironSource(EnvSettingsSource):
    """pydantic-settings' environment source, over a given mapping instead of ``os.environ``."""

    def __init__(self, environ: Mapping[str, str]) -> None:
        self._environ = environ
        super().__init__(ServiceSettings)

    def _load_env_vars(self) -> Mapping[str, str | None]:
        return parse_env_vars(dict(self._environ), self.case_sensitive, self.env_ignore_empty, None)


def _toml_layer(path: Path) -> dict[str, Any]:
    where = f"config file {path}"
    try:
        document = tomllib.loads(path.read_text(encoding="utf-8"))
        data = TomlConfigSettingsSource(ServiceSettings, toml_file=path)()
    except OSError as error:
        raise SettingsError(f"{where}: {error.strerror}") from None
    except tomllib.TOMLDecodeError as error:
        raise SettingsError(f"{where}: {error}") from None
    for key in document:
        if key not in ServiceSettings.model_fields:
            raise SettingsError(f"{where}: unknown setting {key!r}")
    robots = document.get("robots")
    if robots is not None and not (
        isinstance(robots, list) and all(isinstance(r, dict) for r in robots)
    ):
        raise SettingsError(f"{where}: robots must be [[robots]] tables")
    return dict(data)


def _environment_layer(environ: Mapping[str, str]) -> dict[str, Any]:
    try:
        return dict(_EnvironSource(environ)())
    except PydanticSettingsError as error:
        # A complex value (COBOT_HMI_ROBOTS) that is not JSON.
        field = str(error).split('"')[1] if '"' in str(error) else "?"
        cause = error.__cause__ or error
        raise SettingsError(f"{field} (from {env_name(field)}): not valid JSON: {cause}") from None


def load_settings(
    flags: Mapping[str, object] | None = None,
    environ: Mapping[str, str] | None = None,
    config_file: Path | None = None,
) -> ServiceSettings:
    """Layer defaults < TOML file < environment < flags into one checked ``ServiceSettings``.

    ``flags`` holds only what was given on the command line. The TOML file is ``config_file``
    if given, else ``$COBOT_HMI_CONFIG`` if set. The robot list (``[[robots]]``,
    ``COBOT_HMI_ROBOTS``, or the ``robot_host`` shortcut) comes whole from the highest source
    that names robots.
    """
    environ = os.environ if environ is None else environ
    path = config_file or (Path(environ[CONFIG_ENV]) if environ.get(CONFIG_ENV) else None)
    layers: list[tuple[str, dict[str, Any]]] = []  # lowest precedence first
    if path is not None:
        layers.append((f"config file {path}", _toml_layer(path)))
    layers.append(("environment", _environment_layer(environ)))
    flag_values = dict(flags or {})
    for name in flag_values:
        if name not in ServiceSettings.model_fields:
            raise SettingsError(f"unknown setting {name!r}")
    layers.append(("flags", flag_values))

    robot_layer = None
    for index, (source, values) in enumerate(layers):
        given = [key for key in _ROBOT_GROUP if values.get(key)]
        if len(given) > 1:
            raise SettingsError(
                f"{_source_of(source, 'robots')}: give either robot_host or [[robots]], not both"
            )
        if given:
            robot_layer = index
    merged: dict[str, Any] = {}
    sources: dict[str, str] = {}
    for index, (source, values) in enumerate(layers):
        for key, value in values.items():
            if key in _ROBOT_GROUP and index != robot_layer:
                continue
            merged[key] = value
            sources[key] = source
    try:
        return ServiceSettings.model_validate(merged)
    except ValidationError as error:
        raise SettingsError(_describe(error, sources, merged)) from None


def _source_of(source: str, name: str) -> str:
    if source == "environment":
        return env_name(name)
    if source == "flags":
        info = ServiceSettings.model_fields.get(name)
        extra = info.json_schema_extra if info is not None else None
        flag = extra.get("flag") if isinstance(extra, dict) else None
        return str(flag or "--" + name.replace("_", "-"))
    return source


def _describe(error: ValidationError, sources: Mapping[str, str], given: Mapping[str, Any]) -> str:
    """Each problem as ``field (from SOURCE): what, got VALUE``; robots by index and name."""
    lines = []
    for problem in error.errors(include_url=False):
        location = problem["loc"]
        message = str(problem["msg"]).removeprefix("Value error, ")
        if not location:
            if message.startswith("robots:"):
                source = _source_of(sources.get("robots", sources.get("robot_host", "")), "robots")
                message = f"robots (from {source}):" + message.removeprefix("robots:")
            lines.append(message)
            continue
        top = str(location[0])
        where = top
        rest = list(location[1:])
        first = rest[0] if rest else None
        if top == "robots" and isinstance(first, int):
            index = first
            rest.pop(0)
            where = f"robots[{index}]"
            robots = given.get("robots")
            if isinstance(robots, list) and index < len(robots) and isinstance(robots[index], dict):
                name = robots[index].get("name")
                if name is not None:
                    where += f" ({name})"
        if rest:
            where += "." + ".".join(str(part) for part in rest)
        source = _source_of(sources.get(top, "defaults"), top)
        if problem["type"] == "extra_forbidden":
            message = "unknown setting"
        lines.append(f"{where} (from {source}): {message}, got {problem['input']!r}")
    return "; ".join(lines)


# --------------------------------------------------------------------------- command line


def _flag_type(name: str) -> type:
    """The value type of a setting's flag (``Optional`` and ``Annotated`` stripped)."""
    hint: Any = ServiceSettings.model_fields[name].annotation
    if isinstance(hint, types.UnionType) or typing.get_origin(hint) is typing.Union:
        hint = next(a for a in typing.get_args(hint) if a is not type(None))
    if typing.get_origin(hint) is list:
        return str  # a comma-separated list, split by the setting's validator
    return hint if hint in (bool, int, float, Path) else str


def add_arguments(parser: argparse.ArgumentParser, *, only: tuple[str, ...] | None = None) -> None:
    """One flag per setting (``--rpi-ms``), absent from the namespace unless given.

    Also ``--config FILE``, ``--instances CFG,O2T,T2O`` and ``--sizes O2T,T2O`` as on
    ``cobot-hmi scan``. ``only`` limits the flags to some settings (the ``users`` verb).
    The robot list (``robots``) is for the TOML file or ``COBOT_HMI_ROBOTS``.
    """
    parser.add_argument("--config", type=Path, default=argparse.SUPPRESS, help="TOML file")
    for name, info in ServiceSettings.model_fields.items():
        if name in ("robots", "alarms") or (only is not None and name not in only):
            continue
        extra = info.json_schema_extra if isinstance(info.json_schema_extra, dict) else {}
        flag = str(extra.get("flag") or "--" + name.replace("_", "-"))
        kind = _flag_type(name)
        default = info.get_default(call_default_factory=True)
        help_text = f"{info.description} (env {env_name(name)}; default {default})"
        if extra.get("repeatable"):  # --ldap-group-role A=x --ldap-group-role B=y
            parser.add_argument(
                flag,
                dest=name,
                action="append",
                default=argparse.SUPPRESS,
                metavar=name.upper(),
                help=help_text + "; repeatable",
            )
        elif kind is bool:
            parser.add_argument(
                flag,
                dest=name,
                action=argparse.BooleanOptionalAction,
                default=argparse.SUPPRESS,
                help=help_text,
            )
        else:
            parser.add_argument(
                flag,
                dest=name,
                type=kind,
                default=argparse.SUPPRESS,
                metavar=name.upper(),
                help=help_text,
            )
    if only is None:
        parser.add_argument(
            "--instances",
            default=argparse.SUPPRESS,
            metavar="CFG,O2T,T2O",
            help="assembly instances, e.g. "
            f"{cp.CONFIG_INSTANCE.default},{cp.O2T_INSTANCE.default},{cp.T2O_INSTANCE.default}",
        )
        parser.add_argument(
            "--sizes",
            default=argparse.SUPPRESS,
            metavar="O2T,T2O",
            help=f"e.g. {O2T_SIZE},{T2O_SIZE}",
        )


def _ints(text: str, count: int, what: str) -> list[int]:
    parts = text.split(",")
    if len(parts) != count:
        raise SettingsError(f"{what}: expected {count} comma-separated numbers, got {text!r}")
    try:
        return [int(p, 0) for p in parts]
    except ValueError:
        raise SettingsError(f"{what}: expected numbers, got {text!r}") from None


def settings_from_args(
    args: argparse.Namespace, environ: Mapping[str, str] | None = None
) -> ServiceSettings:
    """``load_settings`` with the flags that ``add_arguments`` parsed into ``args``."""
    given = vars(args)
    flags = {name: given[name] for name in ServiceSettings.model_fields if name in given}
    if "instances" in given:
        cfg, o2t, t2o = _ints(given["instances"], 3, "--instances")
        flags |= {"config_instance": cfg, "o2t_instance": o2t, "t2o_instance": t2o}
    if "sizes" in given:
        o2t_size, t2o_size = _ints(given["sizes"], 2, "--sizes")
        flags |= {"o2t_size": o2t_size, "t2o_size": t2o_size}
    return load_settings(flags, environ, given.get("config"))

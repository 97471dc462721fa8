"""Layer: service. The one settings object of the backend service and how it is loaded.

Precedence, highest first: command-line flags, environment variables ``COBOT_HMI_<NAME>``
(``COBOT_HMI_RPI_MS=4``), an optional TOML file (``--config FILE`` or ``COBOT_HMI_CONFIG``)
whose top-level keys are the field names below, then the defaults. Pure: no sockets; imports
nothing of the project except (lazily) the scanner's settings type.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import tomllib
import types
import typing
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Final

from cobot_hmi.layout import CONNECTION_POINTS, O2T_ASSEMBLY, T2O_ASSEMBLY

if TYPE_CHECKING:
    from cobot_hmi.scanner.originator import OriginatorSettings

O2T_SIZE: Final = O2T_ASSEMBLY.size_bytes
T2O_SIZE: Final = T2O_ASSEMBLY.size_bytes
ENV_PREFIX: Final = "COBOT_HMI_"
CONFIG_ENV: Final = "COBOT_HMI_CONFIG"


class SettingsError(ValueError):
    """A setting that cannot be parsed or is out of range; the message names it."""


def _default_state_dir() -> Path:
    base = os.environ.get("XDG_STATE_HOME") or str(Path.home() / ".local" / "state")
    return Path(base) / "cobot-hmi"


def _meta(help_text: str, *, flag: str | None = None) -> dict[str, str | None]:
    return {"help": help_text, "flag": flag}


@dataclass(frozen=True, slots=True)
class ServiceSettings:
    """Everything ``cobot-hmi serve`` can be told. Field names are the TOML keys."""

    # --- the robot and the class 1 connection (passed to the originator)
    robot_host: str = field(default="", metadata=_meta("robot (target) address", flag="--robot"))
    robot_tcp_port: int = field(default=44818, metadata=_meta("robot's EtherNet/IP TCP port"))
    local_host: str = field(default="0.0.0.0", metadata=_meta("local address receiving T→O (UDP)"))
    local_udp_port: int = field(default=2222, metadata=_meta("local UDP port receiving T→O"))
    rpi_ms: float = field(default=10.0, metadata=_meta("requested packet interval, ms"))
    timeout_multiplier: int = field(
        default=2, metadata=_meta("connection timeout = RPI × (4 << multiplier)")
    )
    input_only: bool = field(
        default=False, metadata=_meta("read-only: an input-only connection, never owns outputs")
    )
    large_forward_open: bool = field(default=False, metadata=_meta("use Large Forward Open (0x5B)"))
    config_instance: int = field(
        default=CONNECTION_POINTS.configuration, metadata=_meta("configuration assembly instance")
    )
    o2t_instance: int = field(
        default=CONNECTION_POINTS.o2t, metadata=_meta("O→T (command) assembly instance")
    )
    t2o_instance: int = field(
        default=CONNECTION_POINTS.t2o, metadata=_meta("T→O (robot frame) assembly instance")
    )
    heartbeat_instance: int = field(
        default=CONNECTION_POINTS.input_only,
        metadata=_meta("input-only heartbeat connection point"),
    )
    o2t_size: int = field(default=O2T_SIZE, metadata=_meta("O→T data size, bytes"))
    t2o_size: int = field(default=T2O_SIZE, metadata=_meta("T→O data size, bytes"))
    request_t2o_port: int | None = field(
        default=None, metadata=_meta("ask the robot to send T→O to this UDP port")
    )
    cyclic_niceness: int = field(
        default=0,
        metadata=_meta(
            "nice value of the cyclic I/O thread; below 0 raises its priority (CAP_SYS_NICE)"
        ),
    )
    # --- the web service
    host: str = field(default="127.0.0.1", metadata=_meta("HTTP bind address"))
    port: int = field(default=8000, metadata=_meta("HTTP port"))
    state_dir: Path = field(
        default=_default_state_dir(), metadata=_meta("directory for the users file and database")
    )
    users_file: Path | None = field(
        default=None, metadata=_meta("users file (default: STATE_DIR/users.json)")
    )
    database: Path | None = field(
        default=None, metadata=_meta("SQLite audit/event database (default: STATE_DIR/hmi.db)")
    )
    frontend_dir: Path | None = field(
        default=None, metadata=_meta("built frontend to serve at / (default: frontend/dist)")
    )
    view_requires_login: bool = field(
        default=False, metadata=_meta("reading the API also needs a login")
    )
    session_ttl_s: float = field(
        default=8 * 3600.0, metadata=_meta("a session expires after this long unused, s")
    )
    cookie_secure: bool = field(
        default=False, metadata=_meta("mark the session cookie Secure (behind HTTPS)")
    )
    login_free_attempts: int = field(
        default=3, metadata=_meta("failed logins allowed before slowing down")
    )
    login_delay_max_s: float = field(
        default=30.0, metadata=_meta("longest wait imposed after failed logins, s")
    )
    write_timeout_ms: float = field(
        default=1000.0, metadata=_meta("how long a write waits for the robot to confirm")
    )
    stale_after_ms: float = field(
        default=500.0, metadata=_meta("a frame older than this is flagged stale")
    )
    ws_batch_ms: float = field(
        default=50.0, metadata=_meta("WebSocket broadcast period (frames per message), ms")
    )
    ws_queue_frames: int = field(
        default=400, metadata=_meta("frames a WebSocket client may have queued")
    )
    ws_stall_timeout_s: float = field(
        default=5.0, metadata=_meta("a client whose send is stuck this long is dropped")
    )
    status_interval_s: float = field(
        default=1.0, metadata=_meta("period of WebSocket status messages, s")
    )

    def __post_init__(self) -> None:
        for name in ("robot_tcp_port", "local_udp_port", "port"):
            value = getattr(self, name)
            # Port 0 asks the OS for any free port: useful for the HTTP port in tests.
            if not 0 <= value <= 65535:
                raise SettingsError(f"{name}: {value} is not a port number")
        if self.request_t2o_port is not None and not 1 <= self.request_t2o_port <= 65535:
            raise SettingsError(f"request_t2o_port: {self.request_t2o_port} is not a port number")
        for name in (
            "rpi_ms",
            "session_ttl_s",
            "write_timeout_ms",
            "stale_after_ms",
            "ws_batch_ms",
            "ws_stall_timeout_s",
            "status_interval_s",
        ):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise SettingsError(f"{name}: must be a positive number, got {value}")
        if not -20 <= self.cyclic_niceness <= 19:
            raise SettingsError(f"cyclic_niceness: -20–19, got {self.cyclic_niceness}")
        if not 0 <= self.timeout_multiplier <= 7:
            raise SettingsError(f"timeout_multiplier: 0–7, got {self.timeout_multiplier}")
        if self.ws_queue_frames < 1:
            raise SettingsError(f"ws_queue_frames: at least 1, got {self.ws_queue_frames}")
        if self.login_free_attempts < 0 or self.login_delay_max_s < 0:
            raise SettingsError("login_free_attempts and login_delay_max_s must not be negative")

    @property
    def users_path(self) -> Path:
        return self.users_file if self.users_file is not None else self.state_dir / "users.json"

    @property
    def database_path(self) -> Path:
        return self.database if self.database is not None else self.state_dir / "hmi.db"

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
    def mode(self) -> str:
        return "input_only" if self.input_only else "exclusive_owner"

    def originator_settings(self) -> OriginatorSettings:
        """The scanner's settings for this service's class 1 connection."""
        from cobot_hmi.scanner.originator import OriginatorSettings

        if not self.robot_host:
            raise SettingsError("robot_host: no robot given (--robot HOST or COBOT_HMI_ROBOT_HOST)")
        return OriginatorSettings(
            robot_host=self.robot_host,
            tcp_port=self.robot_tcp_port,
            local_host=self.local_host,
            local_udp_port=self.local_udp_port,
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
            request_t2o_port=self.request_t2o_port,
        )


_FIELDS: Final = {f.name: f for f in dataclasses.fields(ServiceSettings)}
_TYPES: Final = typing.get_type_hints(ServiceSettings)


def _base_type(name: str) -> tuple[type, bool]:
    """The field's value type and whether it may be ``None``."""
    hint = _TYPES[name]
    if isinstance(hint, types.UnionType):
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        return args[0], True
    return hint, False


_TRUE: Final = {"1", "true", "yes", "on"}
_FALSE: Final = {"0", "false", "no", "off"}


def _convert(name: str, value: object, source: str) -> object:
    """A raw value (TOML value or environment text) as the field's type."""
    kind, optional = _base_type(name)
    where = f"{name} (from {source})"
    if optional and (value is None or value == ""):
        return None
    if kind is bool:
        if isinstance(value, bool):
            return value
        text = str(value).strip().lower()
        if text in _TRUE:
            return True
        if text in _FALSE:
            return False
        raise SettingsError(f"{where}: expected true or false, got {value!r}")
    if kind is int:
        if isinstance(value, bool):
            raise SettingsError(f"{where}: expected an integer, got {value!r}")
        try:
            return int(str(value), 0) if isinstance(value, str) else int(str(value))
        except ValueError:
            raise SettingsError(f"{where}: expected an integer, got {value!r}") from None
    if kind is float:
        if isinstance(value, bool):
            raise SettingsError(f"{where}: expected a number, got {value!r}")
        try:
            return float(str(value))
        except ValueError:
            raise SettingsError(f"{where}: expected a number, got {value!r}") from None
    if kind is Path:
        return Path(str(value)).expanduser()
    return str(value)


def env_name(name: str) -> str:
    return ENV_PREFIX + name.upper()


def load_settings(
    flags: Mapping[str, object] | None = None,
    environ: Mapping[str, str] | None = None,
    config_file: Path | None = None,
) -> ServiceSettings:
    """Merge defaults < TOML file < environment < flags into one checked ``ServiceSettings``.

    ``flags`` holds only what was given on the command line (already typed). The TOML file is
    ``config_file`` if given, else ``$COBOT_HMI_CONFIG`` if set.
    """
    environ = os.environ if environ is None else environ
    values: dict[str, object] = {}
    path = config_file or (Path(environ[CONFIG_ENV]) if environ.get(CONFIG_ENV) else None)
    if path is not None:
        try:
            document = tomllib.loads(path.read_text(encoding="utf-8"))
        except OSError as error:
            raise SettingsError(f"config file {path}: {error.strerror}") from None
        except tomllib.TOMLDecodeError as error:
            raise SettingsError(f"config file {path}: {error}") from None
        for key, value in document.items():
            if key not in _FIELDS:
                raise SettingsError(f"config file {path}: unknown setting {key!r}")
            values[key] = _convert(key, value, str(path))
    for name in _FIELDS:
        text = environ.get(env_name(name))
        if text is not None:
            values[name] = _convert(name, text, env_name(name))
    for name, value in (flags or {}).items():
        if name not in _FIELDS:
            raise SettingsError(f"unknown setting {name!r}")
        values[name] = value
    try:
        return ServiceSettings(**values)  # type: ignore[arg-type]
    except TypeError as error:  # a flag given with the wrong Python type
        raise SettingsError(str(error)) from None


# --------------------------------------------------------------------------- command line


def add_arguments(parser: argparse.ArgumentParser, *, only: tuple[str, ...] | None = None) -> None:
    """One flag per setting (``--rpi-ms``), absent from the namespace unless given.

    Also ``--config FILE``, ``--instances CFG,O2T,T2O`` and ``--sizes O2T,T2O`` as on
    ``cobot-hmi scan``. ``only`` limits the flags to some settings (the demo verb).
    """
    parser.add_argument("--config", type=Path, default=argparse.SUPPRESS, help="TOML file")
    for name, f in _FIELDS.items():
        if only is not None and name not in only:
            continue
        flag = f.metadata.get("flag") or "--" + name.replace("_", "-")
        kind, _ = _base_type(name)
        help_text = f"{f.metadata['help']} (env {env_name(name)}; default {f.default})"
        if kind is bool:
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
            f"{CONNECTION_POINTS.configuration},{CONNECTION_POINTS.o2t},{CONNECTION_POINTS.t2o}",
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
    flags = {name: given[name] for name in _FIELDS if name in given}
    if "instances" in given:
        cfg, o2t, t2o = _ints(given["instances"], 3, "--instances")
        flags |= {"config_instance": cfg, "o2t_instance": o2t, "t2o_instance": t2o}
    if "sizes" in given:
        o2t_size, t2o_size = _ints(given["sizes"], 2, "--sizes")
        flags |= {"o2t_size": o2t_size, "t2o_size": t2o_size}
    return load_settings(flags, environ, given.get("config"))

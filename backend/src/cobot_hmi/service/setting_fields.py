"""Layer: service. The settings' vocabulary: how a setting is declared, the value types with
units and checks they share, and the constants every concern's settings use.

Declaring a setting: one field, ``name: type = setting(default, "help", bounds…)``; its flag
(``--name``, or ``flag=``) and environment variable (``COBOT_HMI_NAME``) are derived. Connection
settings take default, bounds and help from ``cobot_hmi.connection_params``, shared with the
emulator and the scanner. Pure: imports nothing of the project but the connection declarations,
the time zones' check (``plant_time``) and, lazily, the layout whose units and field names key
the Sparkplug deadbands."""

from __future__ import annotations

import ipaddress
import os
from pathlib import Path
from typing import Annotated, Any, Final, Literal

from pydantic import AfterValidator, BeforeValidator, Field
from pydantic_settings import NoDecode

from cobot_hmi import connection_params as cp
from cobot_hmi.service.plant_time import check_zone_name

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
TimeZoneName = Annotated[str, AfterValidator(check_zone_name)]
"""An IANA time zone name ("Europe/Berlin") this machine knows, or empty (the host's zone)."""
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


def default_state_dir() -> Path:
    base = os.environ.get("XDG_STATE_HOME") or str(Path.home() / ".local" / "state")
    return Path(base) / "cobot-hmi"

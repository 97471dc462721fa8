"""Layer: service. The one settings object of the backend service, one part per concern.

``ServiceSettings`` is a pydantic-settings model holding each concern's own settings as a part
of its own, each its concern's model in its own room: the robot cell (``cell``:
``robots.cell_settings``), the web service and its limits (``web``: ``web.web_settings``), the
robots' streams and writes (``stream``: ``web.stream_settings``), HTTPS
(``tls``: ``web.tls_settings``), directory login (``directory``: ``access.directory_settings``),
alarms (``alarm_limits``: ``alarms.alarm_settings``), history (``recording``:
``recording.history_settings``), the kiosk (``kiosk``: ``kiosk.kiosk_settings``), robot health
(``health``: ``health.health_service_settings``) and the site's time zone (``site``, here). A
part is given to what uses it and nothing more (the recorder its ``HistorySettings``, a robot
its ``RobotSettings``, …): no part below receives the whole. The doors above the service (the
Sparkplug B edge node, the OPC UA server) add their parts in ``cobot_hmi.settings.HmiSettings``,
the settings of ``cobot-hmi serve``: the service imports neither.

Keys stay flat: a field's name is its key, unique across the parts (``flat_fields``): the TOML
key, ``COBOT_HMI_<NAME>`` its environment variable and ``--name`` its flag (``setting_fields``
declares them; ``config.loading`` layers defaults < TOML < environment < flags;
``config.arguments`` derives the command line), each routed to its part. A TOML file may also
give a part as a table of its keys (``[recording]`` ``history_retention_days = 3``).
``ServiceSettings.from_keys(...)`` reads nothing but its arguments, flat keys or parts (tests,
the demo).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any, Self

from pydantic import BaseModel, ConfigDict, Field, model_validator
from pydantic.fields import FieldInfo
from pydantic_settings import BaseSettings, PydanticBaseSettingsSource, SettingsConfigDict

from cobot_hmi.service.access.directory_settings import DirectorySettings
from cobot_hmi.service.alarms.alarm_settings import AlarmLimitSettings, AlarmSettings
from cobot_hmi.service.health.health_service_settings import HealthServiceSettings
from cobot_hmi.service.kiosk.kiosk_settings import KioskSettings
from cobot_hmi.service.recording.history_settings import HistorySettings
from cobot_hmi.service.robots.cell_settings import CellSettings
from cobot_hmi.service.robots.robot_settings import RobotSettings
from cobot_hmi.service.setting_fields import (
    DEFAULT_DEADBANDS,
    ENV_PREFIX,
    SettingsError,
    TimeZoneName,
    setting,
)
from cobot_hmi.service.web.stream_settings import StreamSettings
from cobot_hmi.service.web.tls_settings import TlsSettings
from cobot_hmi.service.web.web_settings import WebSettings

__all__ = [
    "DEFAULT_DEADBANDS",
    "AlarmSettings",
    "CellSettings",
    "RobotSettings",
    "ServiceSettings",
    "SettingsError",
    "SiteSettings",
]
"""Names other modules import from here (each defined in its concern's module)."""


class SiteSettings(BaseModel):
    """The site's: the plant's time zone (``plant_time``)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    time_zone: TimeZoneName = setting(
        "",
        "the plant's time zone, an IANA name (Europe/Berlin): every time the pages, the CSV "
        "exports and the prints show is in it; empty: the service host's zone",
    )


def settings_part(model: type[BaseModel], what: str) -> Any:
    """A part of the settings: ``model``'s defaults unless given."""
    return Field(default_factory=model, description=what)


# --------------------------------------------------------------------------- the service

_KEYS: dict[type[BaseSettings], dict[str, str]] = {}
"""Each settings class's flat keys and their parts (``ServiceSettings.setting_keys``)."""


class ServiceSettings(BaseSettings):
    """Everything the service itself can be told, one part per concern
    (``cobot_hmi.settings.HmiSettings`` adds the doors above it: Sparkplug B and OPC UA). The
    parts' field names are the flat keys; flags and TOML keys list the parts in this order."""

    model_config = SettingsConfigDict(
        env_prefix=ENV_PREFIX, extra="forbid", frozen=True, case_sensitive=False
    )

    web: WebSettings = settings_part(WebSettings, "the web service and its limits")
    stream: StreamSettings = settings_part(StreamSettings, "the robots' streams and writes")
    tls: TlsSettings = settings_part(TlsSettings, "HTTPS without a proxy")
    directory: DirectorySettings = settings_part(DirectorySettings, "directory login (LDAP)")
    alarm_limits: AlarmLimitSettings = settings_part(
        AlarmLimitSettings, "alarms: limits, user alarms"
    )
    recording: HistorySettings = settings_part(HistorySettings, "history: every frame recorded")
    kiosk: KioskSettings = settings_part(KioskSettings, "the kiosk's plots and the plant's shifts")
    health: HealthServiceSettings = settings_part(
        HealthServiceSettings, "robot health: read from the frames, saved, advised"
    )
    cell: CellSettings = settings_part(CellSettings, "the robots and their connections")
    site: SiteSettings = settings_part(SiteSettings, "the plant's time zone")

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

    # ------------------------------------------------------------ the flat keys

    @classmethod
    def parts(cls) -> dict[str, type[BaseModel]]:
        """Each part's name and model, in order."""
        found: dict[str, type[BaseModel]] = {}
        for name, info in cls.model_fields.items():
            model = info.annotation
            if isinstance(model, type) and issubclass(model, BaseModel):
                found[name] = model
        return found

    @classmethod
    def setting_keys(cls) -> dict[str, str]:
        """Every flat key and the part it belongs to, the parts' fields in order."""
        keys = _KEYS.get(cls)
        if keys is None:
            keys = {}
            parts = cls.parts()
            for part_name, model in parts.items():
                for name in model.model_fields:
                    if name in keys or name in parts:
                        raise TypeError(f"{cls.__name__}: the key {name!r} is not unique")
                    keys[name] = part_name
            _KEYS[cls] = keys
        return keys

    @classmethod
    def flat_fields(cls) -> dict[str, FieldInfo]:
        """Every flat key's declaration (default, help, bounds, flag), in order."""
        parts = cls.parts()
        return {
            name: parts[part_name].model_fields[name]
            for name, part_name in cls.setting_keys().items()
        }

    @classmethod
    def route_keys(cls, data: Mapping[str, Any]) -> dict[str, Any]:
        """``data`` with each flat key moved into its part; a part given whole (a table, a
        model) is its keys' defaults, a flat key beside it wins. Anything else stays where it is,
        for the check to refuse by name."""
        keys, parts = cls.setting_keys(), cls.parts()
        routed: dict[str, Any] = {}
        given: dict[str, dict[str, Any]] = {}
        for key, value in data.items():
            if key in parts and isinstance(value, BaseModel):
                given.setdefault(key, {}).update(
                    {name: getattr(value, name) for name in value.model_fields_set}
                )
            elif key in parts and isinstance(value, Mapping):
                given.setdefault(key, {}).update(value)
            elif key not in keys:
                routed[key] = value
        for key, value in data.items():
            if key in keys:
                given.setdefault(keys[key], {})[key] = value
        return {**routed, **given}

    @model_validator(mode="before")
    @classmethod
    def _route_flat_keys(cls, data: Any) -> Any:
        return cls.route_keys(data) if isinstance(data, Mapping) else data

    @model_validator(mode="after")
    def _check_alarm_robots(self) -> Self:
        """A user alarm names a robot of the cell (when the cell names any)."""
        robots = [robot.name for robot in self.cell.robots]
        for alarm in self.alarm_limits.alarms:
            if alarm.robot is not None and robots and alarm.robot not in robots:
                raise ValueError(
                    f"alarms: {alarm.name!r} names the robot {alarm.robot!r}; "
                    f"known: {', '.join(robots)}"
                )
        return self

    # ------------------------------------------------------------ derived

    @property
    def history_path(self) -> Path:
        """The recordings' directory: ``history_dir``, else in the state directory."""
        given = self.recording.history_dir
        return given if given is not None else self.web.state_dir / "history"

    @classmethod
    def from_keys(cls, **keys: Any) -> Self:
        """The settings from flat keys (``port=8001``, ``history_flush_s=0.5``), as a TOML file
        or the flags give them; parts may be given whole too."""
        return cls.model_validate(keys)

    def given(self) -> dict[str, object]:
        """The flat keys given (not defaulted), with their values."""
        return {
            name: getattr(getattr(self, part_name), name)
            for name, part_name in self.setting_keys().items()
            if name in getattr(self, part_name).model_fields_set
        }

    def replace(self, **changes: object) -> Self:
        """A copy with ``changes`` (flat keys, or parts whole), checked again (robots
        re-inherit the new defaults)."""
        keys = self.setting_keys()
        given = {
            name: value
            for name, value in self.given().items()
            if keys[name] not in changes  # a part given whole replaces its keys
        }
        if changes.get("robots"):
            given.pop("robot_host", None)
        if changes.get("robot_host"):
            given.pop("robots", None)
        return type(self).model_validate({**given, **changes})

"""Layer: plant (a door above the service). The settings of ``cobot-hmi plant``: the service's
own (login, roles, TLS, directory, HTTP bounds, the state directory: what the plant's web API
shares with ``serve``) and the plant's own part (``plant``: ``PlantHostSettings``): its brokers,
groups and host id, and its peers (``--peer``: the other plant processes its page shows). Keys
are flat as everywhere (``ServiceSettings.flat_fields``): ``--mqtt-url`` is repeatable,
``COBOT_HMI_MQTT_URLS`` a comma-separated list, ``mqtt_urls`` a TOML list.
"""

from __future__ import annotations

from pathlib import Path
from urllib.parse import urlsplit

from pydantic import BaseModel, ConfigDict, Field, field_validator

from cobot_hmi.service.service_settings import ServiceSettings, settings_part
from cobot_hmi.service.setting_fields import (
    SPARKPLUG_ID_PATTERN,
    CommaList,
    ReadableFile,
    setting,
)


class PlantHostSettings(BaseModel):
    """The plant's Sparkplug host application: its brokers, the groups it follows, its id."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    mqtt_urls: CommaList = Field(
        default_factory=list,
        description="MQTT broker, mqtt://HOST:PORT or mqtts://HOST:PORT; several: the plant "
        "moves to the next when one goes away",
        json_schema_extra={"flag": "--mqtt-url", "repeatable": True},
    )
    mqtt_user: str = setting("", "MQTT user name (empty: none)")
    mqtt_password: str = setting("", "MQTT password (prefer COBOT_HMI_MQTT_PASSWORD)")
    mqtt_ca_file: ReadableFile | None = setting(
        None, "CA certificates for mqtts:// (default: the system's)"
    )
    plant_groups: CommaList = Field(
        default_factory=list,
        description="Sparkplug groups this plant process follows (none: every group)",
        json_schema_extra={"flag": "--group", "repeatable": True},
    )
    plant_host_id: str = setting(
        "cobot-hmi-plant",
        "Sparkplug host application id (its STATE topic spBv1.0/STATE/<id>)",
        pattern=SPARKPLUG_ID_PATTERN,
    )
    plant_rebirth_interval_s: float = setting(
        5.0, "at most one rebirth request per edge node this often, s", gt=0, le=3600
    )
    plant_peers: CommaList = Field(
        default_factory=list,
        description="another plant process (http(s)://HOST:PORT) whose cells and alarms this "
        "one's page and API show beside its own (a plant split by --group over processes)",
        json_schema_extra={"flag": "--peer", "repeatable": True},
    )
    plant_peer_token: str = setting(
        "", "bearer token for the peers that ask for a login (a viewer's API token there)"
    )

    @field_validator("plant_peers")
    @classmethod
    def _peer_urls(cls, urls: list[str]) -> list[str]:
        for url in urls:
            parsed = urlsplit(url)
            if parsed.scheme not in ("http", "https") or not parsed.hostname:
                raise ValueError(f"a peer is http(s)://HOST:PORT, not {url!r}")
        return urls


class PlantSettings(ServiceSettings):
    """Everything ``cobot-hmi plant`` can be told (the robot settings it inherits are unused)."""

    plant: PlantHostSettings = settings_part(PlantHostSettings, "the plant's host application")

    @property
    def plant_history_path(self) -> Path:
        """The plant's hourly Parquet segments."""
        return self.web.state_dir / "plant-history"

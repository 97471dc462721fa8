"""Layer: sparkplug. The Sparkplug B edge node's settings (MQTT broker, ids, report-by-exception
deadbands, rate, buffer; docs/operations.md "Sparkplug"): its flat ``mqtt_*`` and
``sparkplug_*`` fields, the ``sparkplug`` part of the settings of ``serve``
(``cobot_hmi.settings.HmiSettings``), handed to the edge node alone."""

from __future__ import annotations

import socket

from pydantic import BaseModel, ConfigDict

from cobot_hmi.service.setting_fields import (
    DEFAULT_DEADBANDS,
    SPARKPLUG_ID_PATTERN,
    Deadbands,
    ReadableFile,
    SparkplugId,
    setting,
)


class SparkplugSettings(BaseModel):
    """The edge node's settings (off unless ``mqtt_url`` is set)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

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
    sparkplug_hmi_url: str = setting(
        "",
        "the cell's HMI address the NBIRTH names (the plant's page links to it); default: "
        "http(s)://HOST:PORT/ of this service (this machine's name when HOST binds every address)",
        pattern=r"^$|^https?://[^\s]+$",
    )

    @property
    def sparkplug_node_id(self) -> str:
        """The edge node id: the setting, else the host name (``+ # /`` made ``_``)."""
        if self.sparkplug_node:
            return self.sparkplug_node
        name = socket.gethostname() or "cobot-hmi"
        return name.replace("+", "_").replace("#", "_").replace("/", "_")

    def hmi_url(self, host: str, port: int, *, tls: bool) -> str:
        """``sparkplug_hmi_url``, else the service's own address: ``host`` (this machine's name
        when it binds every address, which no browser can open) and ``port``."""
        if self.sparkplug_hmi_url:
            return self.sparkplug_hmi_url
        if host in ("", "0.0.0.0", "::"):
            host = socket.gethostname() or "localhost"
        elif ":" in host:
            host = f"[{host}]"  # an IPv6 literal in a URL
        return f"{'https' if tls else 'http'}://{host}:{port}/"

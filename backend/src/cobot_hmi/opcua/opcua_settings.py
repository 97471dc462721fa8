"""Layer: service (OPC UA). The OPC UA server's settings, declared once.

``OpcUaSettings`` is a pydantic model of the ``opcua_*`` settings, the ``opcua`` part of the
settings of ``serve`` (``cobot_hmi.settings.HmiSettings``): each field is a TOML key, a
``COBOT_HMI_OPCUA_*`` variable and a ``--opcua-*`` flag of ``serve`` like every other setting
(the help text below is the flag's). Pure: imports nothing of the project.
"""

from __future__ import annotations

import ipaddress
from pathlib import Path
from typing import Final
from urllib.parse import urlsplit

from pydantic import BaseModel, ConfigDict, Field

DEFAULT_PORT: Final = 4840
"""OPC UA's registered TCP port (IANA, opc.tcp)."""
URL_PATTERN: Final = r"^$|^opc\.tcp://(\[[0-9A-Fa-f:.]+\]|[^/:\[\]]+)(:\d{1,5})?/?$"


class OpcUaSettings(BaseModel):
    """Everything the OPC UA server can be told (docs/operations.md, "OPC UA")."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    opcua_url: str = Field(
        default="",
        description=(
            f"serve OPC UA at opc.tcp://HOST[:PORT] (port {DEFAULT_PORT} unless given); "
            "empty: no OPC UA server"
        ),
        pattern=URL_PATTERN,
    )
    opcua_writes: bool = Field(
        default=False,
        description=(
            "OPC UA clients may write the command image (through the write pipeline: the "
            "operator role and control)"
        ),
    )
    opcua_monitoring_hz: float = Field(
        default=10.0,
        description="rate at which the OPC UA values follow the frames, per second",
        gt=0,
        le=100,
        allow_inf_nan=False,
    )
    opcua_allow_no_security: bool = Field(
        default=False,
        description=(
            "also offer SecurityPolicy None (no signature, no encryption) on an address other "
            "than loopback"
        ),
    )
    opcua_trust_dir: Path | None = Field(
        default=None,
        description=(
            "client certificates trusted for Sign and SignAndEncrypt, DER or PEM files "
            "(default: STATE_DIR/opcua/pki/trusted)"
        ),
    )

    @property
    def opcua_enabled(self) -> bool:
        return bool(self.opcua_url)

    @property
    def opcua_bind(self) -> tuple[str, int]:
        """The URL's host and port (the default port when it names none)."""
        parts = urlsplit(self.opcua_url)
        host = parts.hostname or ""
        return host, parts.port or DEFAULT_PORT

    @property
    def opcua_loopback(self) -> bool:
        """Whether the server binds a loopback address only (``localhost`` counts)."""
        host = self.opcua_bind[0]
        if host == "localhost":
            return True
        try:
            return ipaddress.ip_address(host).is_loopback
        except ValueError:  # a host name: whatever it resolves to, not known to be loopback
            return False

    def opcua_pki_dir(self, state_dir: Path) -> Path:
        """The server's own certificate and key (``own/``), ``trusted/`` and ``rejected/``."""
        return state_dir / "opcua" / "pki"

    def opcua_trusted_dir(self, state_dir: Path) -> Path:
        if self.opcua_trust_dir is not None:
            return self.opcua_trust_dir.expanduser()
        return self.opcua_pki_dir(state_dir) / "trusted"

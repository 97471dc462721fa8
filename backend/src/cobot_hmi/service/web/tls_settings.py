"""Layer: service. HTTPS without a proxy: its settings, declared once.

``TlsSettings`` is a pydantic model of the ``tls_*`` settings and ``http_redirect_port``, the
``tls`` part of the service's settings (``service.settings.ServiceSettings``): each field is a
TOML key, a ``COBOT_HMI_*`` variable and a flag of ``serve`` like every other setting (the help text
below is the flag's; docs/operations.md "Certificates"). The files are read when the service
starts and again whenever they change (``service.api.tls``). Imports nothing of the project.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, model_validator


def _readable(path: Path | None) -> Path | None:
    if path is None:
        return None
    path = path.expanduser()
    try:
        path.read_bytes()
    except OSError as error:
        raise ValueError(f"{path}: {error.strerror}") from None
    return path


PemFile = Annotated[Path | None, AfterValidator(_readable)]


class TlsSettings(BaseModel):
    """Everything HTTPS can be told (docs/operations.md, "Certificates")."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    tls_cert: PemFile = Field(
        default=None,
        description="PEM certificate (its chain after it): serve HTTPS and WSS instead of HTTP "
        "(with --tls-key); a changed file is used from the next connection on",
    )
    tls_key: PemFile = Field(default=None, description="PEM private key of --tls-cert")
    http_redirect_port: int | None = Field(
        default=None,
        ge=1,
        le=65535,
        description="with TLS: also listen for plain HTTP on this port, answering every request "
        "with a redirect to HTTPS and nothing else",
    )

    @model_validator(mode="after")
    def _pair(self) -> TlsSettings:
        if (self.tls_cert is None) != (self.tls_key is None):
            raise ValueError("tls_cert and tls_key go together: give both, or neither")
        if self.http_redirect_port is not None and self.tls_cert is None:
            raise ValueError("http_redirect_port redirects to HTTPS: give tls_cert and tls_key")
        return self

    @property
    def tls_enabled(self) -> bool:
        return self.tls_cert is not None

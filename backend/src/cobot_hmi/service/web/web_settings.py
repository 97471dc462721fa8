"""Layer: service. The web service's settings: HTTP, sessions and logins, and the security
limits (service/api/security.py and http_limits.py; docs/operations.md "Security"). The robots'
streams and writes have theirs (``stream_settings``)."""

from __future__ import annotations

from pathlib import Path

from pydantic import BaseModel, ConfigDict, Field

from cobot_hmi.service.setting_fields import (
    CommaList,
    ExpandedPath,
    Port,
    ProxyList,
    Seconds,
    default_state_dir,
    setting,
)


class WebSettings(BaseModel):
    """The HTTP door and its limits."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    # --- the web service
    host: str = setting("127.0.0.1", "HTTP bind address")
    port: Port = setting(8000, "HTTP port")
    state_dir: ExpandedPath = Field(
        default_factory=default_state_dir,
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
        # backend/src/cobot_hmi/service/web/web_settings.py → the repository's frontend/dist
        return Path(__file__).resolve().parents[5] / "frontend" / "dist"

"""Layer: service. The directory login's settings (LDAP / Active Directory), declared once.

``DirectorySettings`` is a pydantic model of the ``ldap_*`` settings, the ``directory`` part of
the service's settings (``service.settings.ServiceSettings``): each field is a TOML key, a
``COBOT_HMI_LDAP_*`` variable and a ``--ldap-*`` flag of ``serve`` like every other setting
(the help text below is the flag's; docs/operations.md "Directory (LDAP)").

``ldap_group_role`` maps group DNs to roles. On the command line it is ``--ldap-group-role
GROUP_DN=ROLE``, repeated; each is split at its LAST ``=`` (a DN is full of ``=``). In TOML
it is a list of such strings or a table ``{"cn=ops,dc=example,dc=org" = "operator"}``; in
``COBOT_HMI_LDAP_GROUP_ROLE`` a JSON list or table, or ``DN=ROLE`` entries separated by ``;``
(which a DN can hold only escaped, RFC 4514 §2.4). Group DNs are kept in one normal form
(``normal_dn``) so a group the directory names ``CN=Ops, OU=Groups,…`` is the configured
``cn=ops,ou=groups,…``. Imports nothing of the project.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Final, Literal

from ldap3.core.exceptions import LDAPInvalidDnError
from ldap3.utils.dn import parse_dn
from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    SecretStr,
    model_validator,
)
from pydantic_settings import NoDecode

USER_PLACEHOLDER: Final = "{user}"
LDAP_URL_PATTERN: Final = r"^$|^ldaps?://[^\s/?#]+/?$"
RoleName = Literal["viewer", "operator", "admin"]


def normal_dn(dn: str) -> str:
    """``dn`` in one comparable form: attribute types and values lower-case, no spaces around
    separators (LDAP compares the values of cn, ou, dc … ignoring case). ``ValueError`` when
    it is not a DN."""
    try:
        parts = parse_dn(dn, escape=False, strip=True)
    except LDAPInvalidDnError as error:
        raise ValueError(f"{dn!r} is not a DN ({error})") from None
    if not parts:
        raise ValueError("an empty DN")
    return ",".join(f"{kind.lower()}={value.lower()}" for kind, value, _ in parts)


def _split_group_roles(value: object) -> object:
    """``DN=ROLE`` entries (flags, a TOML list, a variable) to ``{DN: ROLE}``; a table passes."""
    if isinstance(value, str):
        text = value.strip()
        if text.startswith(("[", "{")):
            try:
                value = json.loads(text)
            except json.JSONDecodeError as error:
                raise ValueError(f"not valid JSON: {error}") from None
        else:
            value = [part for part in text.replace("\n", ";").split(";") if part.strip()]
    if isinstance(value, (list, tuple)):
        pairs: dict[str, str] = {}
        for entry in value:
            if not isinstance(entry, str):
                raise ValueError(f"expected GROUP_DN=ROLE, got {entry!r}")
            dn, sep, role = entry.strip().rpartition("=")
            if not sep or not dn:
                raise ValueError(f"expected GROUP_DN=ROLE, got {entry.strip()!r}")
            dn, role = dn.strip(), role.strip()
            if pairs.setdefault(dn, role) != role:
                raise ValueError(f"the group {dn!r} is given twice, as {pairs[dn]} and {role}")
        return pairs
    return value


def _normal_group_dns(value: dict[str, RoleName]) -> dict[str, RoleName]:
    normal: dict[str, RoleName] = {}
    for dn, role in value.items():
        key = normal_dn(dn)
        if key in normal and normal[key] != role:
            raise ValueError(f"the group {dn!r} is given twice, as {normal[key]} and {role}")
        normal[key] = role
    return normal


GroupRoles = Annotated[
    dict[str, RoleName],
    NoDecode,
    BeforeValidator(_split_group_roles),
    AfterValidator(_normal_group_dns),
]


def _readable_ca(path: Path | None) -> Path | None:
    if path is None:
        return None
    path = path.expanduser()
    try:
        path.read_bytes()
    except OSError as error:
        raise ValueError(f"{path}: {error.strerror}") from None
    return path


class DirectorySettings(BaseModel):
    """Everything the directory login can be told (docs/operations.md, "Directory (LDAP)")."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    ldap_url: str = Field(
        default="",
        pattern=LDAP_URL_PATTERN,
        description="log users in against this directory: ldap://HOST[:PORT] or "
        "ldaps://HOST[:PORT]; empty: local users only",
    )
    ldap_start_tls: bool = Field(
        default=False, description="upgrade an ldap:// connection with StartTLS before binding"
    )
    ldap_ca_file: Annotated[Path | None, AfterValidator(_readable_ca)] = Field(
        default=None,
        description="PEM file of the CA(s) the directory's certificate must chain to (ldaps:// "
        "or StartTLS; default: the system's trusted CAs)",
    )
    ldap_user_dn: str = Field(
        default="",
        description="a user's DN from their name, e.g. uid={user},ou=people,dc=example,dc=org "
        "(the name escaped); empty: search for it (ldap_search_base)",
    )
    ldap_bind_dn: str = Field(
        default="",
        description="service account that searches users and reads groups (empty: anonymous)",
    )
    ldap_bind_password: SecretStr = Field(
        default=SecretStr(""), description="the service account's password"
    )
    ldap_search_base: str = Field(
        default="",
        description="where users are searched (search-then-bind), e.g. dc=example,dc=org",
    )
    ldap_user_filter: str = Field(
        default="(uid={user})",
        description="filter that finds a user by name (the name escaped); Active Directory: "
        "(sAMAccountName={user})",
    )
    ldap_group_role: GroupRoles = Field(
        default_factory=dict,
        description="GROUP_DN=ROLE: members of the group get the role (viewer, operator, "
        "admin; the highest wins)",
        json_schema_extra={"repeatable": True},
    )
    ldap_timeout_s: float = Field(
        default=5.0,
        gt=0,
        le=120,
        allow_inf_nan=False,
        description="connecting to and each answer of the directory, s",
    )
    ldap_role_refresh_s: float = Field(
        default=300.0,
        gt=0,
        allow_inf_nan=False,
        description="a directory user's role is read again this often while they have a "
        "session (a changed role ends it), s",
    )

    @property
    def directory_enabled(self) -> bool:
        return bool(self.ldap_url)

    @model_validator(mode="after")
    def _check_directory(self) -> DirectorySettings:
        if not self.ldap_url:
            return self
        if bool(self.ldap_user_dn) == bool(self.ldap_search_base):
            raise ValueError(
                "ldap_user_dn or ldap_search_base: give one (a DN template, or where to search)"
            )
        if self.ldap_user_dn:
            if self.ldap_user_dn.count(USER_PLACEHOLDER) != 1:
                raise ValueError(f"ldap_user_dn: must hold {USER_PLACEHOLDER} once")
            normal_dn(self.ldap_user_dn.replace(USER_PLACEHOLDER, "x"))
        else:
            normal_dn(self.ldap_search_base)
            user_filter = self.ldap_user_filter
            if USER_PLACEHOLDER not in user_filter or not (
                user_filter.startswith("(") and user_filter.endswith(")")
            ):
                raise ValueError(
                    f"ldap_user_filter: a filter in parentheses with {USER_PLACEHOLDER}, "
                    f"got {user_filter!r}"
                )
        if self.ldap_bind_dn:
            normal_dn(self.ldap_bind_dn)
        elif self.ldap_bind_password.get_secret_value():
            raise ValueError("ldap_bind_password: given without ldap_bind_dn")
        if self.ldap_start_tls and self.ldap_url.startswith("ldaps:"):
            raise ValueError("ldap_start_tls: an ldaps:// connection is TLS already")
        if not self.ldap_group_role:
            raise ValueError(
                "ldap_group_role: map at least one group to a role (GROUP_DN=ROLE), or no "
                "directory user could log in"
            )
        return self

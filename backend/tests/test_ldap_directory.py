"""The directory login's own parts without the service: ``Directory`` against the real slapd
(tests/ldap_support.py) in each way of finding the user (DN template, search with the service
account, anonymous search) and each transport (LDAP, StartTLS, LDAPS), and the ``ldap_*``
settings from flags, environment and TOML.
"""

from __future__ import annotations

import argparse
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from cobot_hmi.service.access.directory import Directory, DirectoryUnreachableError, NoRoleError
from cobot_hmi.service.access.directory_settings import DirectorySettings
from cobot_hmi.service.config.arguments import add_arguments
from cobot_hmi.service.config.arguments import settings_from_args as from_args
from cobot_hmi.service.config.loading import load_settings
from cobot_hmi.service.service_settings import SettingsError
from conftest import free_tcp_port
from ldap_support import (
    ADMINS,
    BASE_DN,
    GROUP_ROLES,
    INJECTIONS,
    OPERATORS,
    SERVICE_DN,
    SERVICE_PASSWORD,
    USER_DN_TEMPLATE,
    USERS,
    VIEWERS,
    Slapd,
    needs_slapd,
    running_slapd,
)

MODES = ("template", "search", "anonymous search")


@pytest.fixture(scope="session")
def slapd(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Slapd]:
    with running_slapd(tmp_path_factory.mktemp("slapd")) as running:
        yield running


def directory(slapd: Slapd, mode: str = "template", **changes: Any) -> Directory:
    settings: dict[str, Any] = {"ldap_url": slapd.url, "ldap_group_role": GROUP_ROLES}
    if mode == "template":
        settings["ldap_user_dn"] = USER_DN_TEMPLATE
    else:
        settings["ldap_search_base"] = BASE_DN
        if mode == "search":
            settings |= {"ldap_bind_dn": SERVICE_DN, "ldap_bind_password": SERVICE_PASSWORD}
    return Directory(DirectorySettings.model_validate(settings | changes))


def role(directory: Directory, name: str) -> str:
    account = directory.authenticate(name, USERS[name][0])
    assert account is not None, name
    return account.user.role.label


@needs_slapd
@pytest.mark.parametrize("mode", MODES)
def test_each_way_of_finding_the_user_reads_the_same_roles(slapd: Slapd, mode: str) -> None:
    ask = directory(slapd, mode)
    assert [role(ask, name) for name in ("olga", "vera", "adam", "gina")] == [
        "operator",
        "viewer",
        "admin",
        "viewer",
    ]
    with pytest.raises(NoRoleError, match="nora is in none of the directory groups"):
        ask.authenticate("nora", USERS["nora"][0])
    assert ask.authenticate("olga", "wrong") is None
    assert ask.authenticate("olga", "") is None  # never an anonymous bind
    assert ask.authenticate("nobody", "whatever") is None
    for name in INJECTIONS:
        assert ask.authenticate(name, USERS["olga"][0]) is None, name
        assert ask.authenticate(name, USERS["adam"][0]) is None, name


@needs_slapd
def test_group_dns_match_whatever_their_case_and_spacing(slapd: Slapd) -> None:
    """The directory writes memberOf as it stores the group's DN; the setting may differ."""
    shouted = [
        f"{ADMINS.upper().replace(',', ', ')}=admin",
        f"{OPERATORS.upper()}=operator",
        f"{VIEWERS}=viewer",
    ]
    ask = directory(slapd, ldap_group_role=shouted)
    assert role(ask, "adam") == "admin"
    assert role(ask, "olga") == "operator"


@needs_slapd
def test_tls_needs_the_ca_that_signed_the_directorys_certificate(slapd: Slapd) -> None:
    ldaps: dict[str, Any] = {"ldap_url": slapd.ldaps_url}
    start_tls: dict[str, Any] = {"ldap_start_tls": True}
    ca: dict[str, Any] = {"ldap_ca_file": slapd.ca_file}
    assert role(directory(slapd, **ldaps, **ca), "olga") == "operator"
    assert role(directory(slapd, "search", **start_tls, **ca), "vera") == "viewer"
    for untrusted in (ldaps, start_tls):  # the system's CAs never signed the test's CA
        with pytest.raises(DirectoryUnreachableError, match="CERTIFICATE_VERIFY_FAILED"):
            directory(slapd, **untrusted).authenticate("olga", USERS["olga"][0])


@needs_slapd
def test_a_refused_service_account_is_the_directory_being_unusable(slapd: Slapd) -> None:
    ask = directory(slapd, "search", ldap_bind_password="not-the-service-password")
    with pytest.raises(DirectoryUnreachableError, match="service account's bind was refused"):
        ask.authenticate("olga", USERS["olga"][0])


@needs_slapd
def test_nothing_listening_is_unreachable(slapd: Slapd) -> None:
    ask = directory(slapd, ldap_url=f"ldap://127.0.0.1:{free_tcp_port()}", ldap_timeout_s=5)
    with pytest.raises(DirectoryUnreachableError, match="directory unreachable"):
        ask.authenticate("olga", USERS["olga"][0])


@needs_slapd
async def test_a_refresh_reads_roles_again_and_keeps_them_while_the_directory_is_away(
    slapd: Slapd,
) -> None:
    ask = directory(slapd, "search")
    user = await ask.login("gina", USERS["gina"][0])
    assert user is not None and user.role.label == "viewer"
    slapd.move("gina", leave=VIEWERS, join=OPERATORS)
    try:
        await ask.refresh({"gina"})
        refreshed = ask.user("gina")
        assert refreshed is not None and refreshed.role.label == "operator"
        slapd.stop()
        try:
            await ask.refresh({"gina"})  # unreachable: the role last read stands
        finally:
            slapd.start()
        assert ask.user("gina") == refreshed
        await ask.refresh(set())  # no session, but just logged in: kept a while
        assert ask.user("gina") == refreshed
    finally:
        slapd.move("gina", leave=OPERATORS, join=VIEWERS)
    await ask.refresh({"gina"})
    again = ask.user("gina")
    assert again is not None and again.role.label == "viewer"


# --------------------------------------------------------------------------- settings

TEMPLATE = "uid={user},ou=people,dc=example,dc=org"
OPS = "cn=ops,ou=groups,dc=example,dc=org"
VIEW = "cn=view,ou=groups,dc=example,dc=org"


def test_group_roles_from_repeated_flags_split_at_the_last_equals_sign() -> None:
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    args = parser.parse_args(
        [
            "--robot=127.0.0.2",
            "--ldap-url=ldap://127.0.0.1:3389",
            f"--ldap-user-dn={TEMPLATE}",
            "--ldap-group-role",
            f"CN=Ops, OU=Groups,DC=example,DC=org={'operator'}",
            "--ldap-group-role",
            f"{VIEW}=viewer",
        ]
    )
    settings = from_args(args, environ={})
    assert settings.directory.ldap_group_role == {OPS: "operator", VIEW: "viewer"}
    assert settings.directory.ldap_user_dn == TEMPLATE


def test_the_same_settings_from_the_environment_and_toml(tmp_path: Path) -> None:
    environ = {
        "COBOT_HMI_LDAP_URL": "ldaps://dc1.example.org:636",
        "COBOT_HMI_LDAP_SEARCH_BASE": "dc=example,dc=org",
        "COBOT_HMI_LDAP_BIND_DN": "cn=svc,dc=example,dc=org",
        "COBOT_HMI_LDAP_BIND_PASSWORD": "s3cret",
        "COBOT_HMI_LDAP_GROUP_ROLE": f"{OPS}=operator; {VIEW}=viewer",
    }
    settings = load_settings({"robot_host": "127.0.0.2"}, environ)
    assert settings.directory.ldap_group_role == {OPS: "operator", VIEW: "viewer"}
    assert settings.directory.ldap_bind_password.get_secret_value() == "s3cret"
    assert "s3cret" not in repr(settings)
    as_json = load_settings(
        {"robot_host": "127.0.0.2"}, environ | {"COBOT_HMI_LDAP_GROUP_ROLE": f'["{OPS}=admin"]'}
    )
    assert as_json.directory.ldap_group_role == {OPS: "admin"}
    config = tmp_path / "hmi.toml"
    config.write_text(
        'ldap_url = "ldap://127.0.0.1:3389"\n'
        "ldap_start_tls = true\n"
        'ldap_search_base = "dc=example,dc=org"\n'
        'ldap_user_filter = "(sAMAccountName={user})"\n'
        f'ldap_group_role = ["{OPS}=operator"]\n'
    )
    from_toml = load_settings({"robot_host": "127.0.0.2"}, {}, config)
    assert (
        from_toml.directory.ldap_start_tls
        and from_toml.directory.ldap_user_filter == "(sAMAccountName={user})"
    )
    assert from_toml.directory.ldap_group_role == {OPS: "operator"}
    table = tmp_path / "table.toml"
    table.write_text(
        f'ldap_url = "ldap://h"\nldap_user_dn = "{TEMPLATE}"\n'
        f'[ldap_group_role]\n"{VIEW}" = "viewer"\n'
    )
    assert load_settings({"robot_host": "x"}, {}, table).directory.ldap_group_role == {
        VIEW: "viewer"
    }


@pytest.mark.parametrize(
    ("given", "complaint"),
    [
        ({"ldap_group_role": []}, "ldap_group_role: map at least one group"),
        ({"ldap_group_role": [f"{OPS}=king"]}, "Input should be 'viewer', 'operator' or 'admin'"),
        ({"ldap_group_role": ["operator"]}, "expected GROUP_DN=ROLE"),
        ({"ldap_group_role": [f"{OPS}=operator", f"{OPS}=viewer"]}, "is given twice"),
        ({"ldap_user_dn": "uid=x,dc=org", "ldap_group_role": [f"{OPS}=admin"]}, "{user} once"),
        ({"ldap_url": "http://h", "ldap_user_dn": TEMPLATE}, "ldap_url"),
        ({"ldap_start_tls": True, "ldap_url": "ldaps://h"}, "TLS already"),
        ({"ldap_bind_password": "x"}, "given without ldap_bind_dn"),
        ({"ldap_search_base": "dc=x", "ldap_user_filter": "uid={user}"}, "in parentheses"),
    ],
)
def test_incoherent_directory_settings_are_refused(given: dict[str, Any], complaint: str) -> None:
    settings: dict[str, Any] = {
        "robot_host": "127.0.0.2",
        "ldap_url": "ldap://127.0.0.1:3389",
        "ldap_group_role": [f"{OPS}=operator"],
    }
    if "ldap_search_base" not in given and "ldap_user_dn" not in given:
        settings["ldap_user_dn"] = TEMPLATE
    with pytest.raises(SettingsError, match=re.escape(complaint)):
        load_settings(settings | given, {})

"""Verbs of the backend service: ``serve`` and ``users`` (``demo`` is ``demo_verb``).

``serve`` runs the service against the robots (or emulators). ``users add`` manages the users
file; ``users token`` and ``revoke`` its long-lived API tokens.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import getpass
import math
import sys
import time


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    from cobot_hmi.cli.hmi_settings import add_hmi_arguments

    serve = subparsers.add_parser(
        "serve",
        help="run the web service against the robots (REST, WebSocket, frontend)",
        description=(
            "Hold a class 1 connection to each robot and serve the HMI. One robot: --robot HOST "
            "[--robot-name NAME]; several: [[robots]] tables in the TOML file (--config; "
            "docs/operations.md). Settings come from the flags, then COBOT_HMI_* environment "
            "variables, then the TOML file; the top-level connection settings are every "
            "robot's defaults."
        ),
    )
    add_hmi_arguments(serve)
    serve.set_defaults(handler=_serve)

    users = subparsers.add_parser("users", help="manage the service's users file")
    users_verbs = users.add_subparsers(dest="users_verb", required=True, metavar="ACTION")
    add = users_verbs.add_parser(
        "add",
        help="add a user or reset one's role and password",
        description="Add NAME with ROLE; the password is asked twice, or read from stdin.",
    )
    add.add_argument("name")
    add.add_argument("--role", default="operator", help="viewer, operator or admin")
    add.add_argument("--password-stdin", action="store_true", help="read the password from stdin")
    add_hmi_arguments(add, only=("state_dir", "users_file"))
    add.set_defaults(handler=_users_add)
    listing = users_verbs.add_parser("list", help="list users and roles")
    add_hmi_arguments(listing, only=("state_dir", "users_file"))
    listing.set_defaults(handler=_users_list)
    token = users_verbs.add_parser(
        "token",
        help="issue a long-lived API token (kiosks, scripts)",
        description="Issue (or re-issue) the bearer token NAME with ROLE and print it once; "
        "the users file keeps only its SHA-256. A kiosk opens /kiosk?token=… or sends "
        "'Authorization: Bearer …'.",
    )
    token.add_argument("name")
    token.add_argument("--role", default="viewer", help="viewer (default), operator or admin")
    token.add_argument(
        "--expires-days", type=float, default=None, help="lifetime in days (default: until revoked)"
    )
    add_hmi_arguments(token, only=("state_dir", "users_file"))
    token.set_defaults(handler=_users_token)
    revoke = users_verbs.add_parser("revoke", help="revoke the API token NAME")
    revoke.add_argument("name")
    add_hmi_arguments(revoke, only=("state_dir", "users_file"))
    revoke.set_defaults(handler=_users_revoke)


def _fail(reason: str) -> int:
    print(f"cobot-hmi: {reason}", file=sys.stderr)
    return 2


def _serve(args: argparse.Namespace) -> int:
    from cobot_hmi.cli.hmi_settings import hmi_settings
    from cobot_hmi.composition import build_service
    from cobot_hmi.service.api.server import prepare_process, serve
    from cobot_hmi.service.api.tls import TlsError
    from cobot_hmi.service.service_settings import SettingsError

    try:
        settings = hmi_settings(args)
        settings.cell.require_robots()
    except SettingsError as error:
        return _fail(str(error))
    prepare_process()
    try:
        with contextlib.suppress(KeyboardInterrupt):  # uvicorn re-raises the signal it handled
            asyncio.run(serve(settings, build_service))
    except TlsError as error:
        return _fail(f"TLS: {error}")
    return 0


def _users_add(args: argparse.Namespace) -> int:
    from cobot_hmi.cli.hmi_settings import hmi_settings
    from cobot_hmi.service.access.users import Role, UsersError, UsersFile
    from cobot_hmi.service.service_settings import SettingsError

    try:
        settings = hmi_settings(args)
        role = Role.parse(args.role)
        if args.password_stdin:
            password = sys.stdin.readline().rstrip("\r\n")
        else:
            password = getpass.getpass(f"password for {args.name}: ")
            if getpass.getpass("again: ") != password:
                return _fail("the passwords differ")
        user = UsersFile(settings.web.users_path).add(args.name, role, password)
    except (SettingsError, UsersError) as error:
        return _fail(str(error))
    print(f"{user.name}: {user.role.label} in {settings.web.users_path}")
    return 0


def _users_list(args: argparse.Namespace) -> int:
    from cobot_hmi.cli.hmi_settings import hmi_settings
    from cobot_hmi.service.access.users import UsersError, UsersFile
    from cobot_hmi.service.service_settings import SettingsError

    try:
        settings = hmi_settings(args)
        users_file = UsersFile(settings.web.users_path)
        users = users_file.users()
        tokens = users_file.tokens()
    except (SettingsError, UsersError) as error:
        return _fail(str(error))
    for user in users:
        print(f"{user.name}\t{user.role.label}")
    for api_token in tokens:
        expires = (
            "never"
            if api_token.expires is None
            else time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(api_token.expires))
        )
        print(f"token:{api_token.name}\t{api_token.role.label}\texpires {expires}")
    return 0


def _users_token(args: argparse.Namespace) -> int:
    from cobot_hmi.cli.hmi_settings import hmi_settings
    from cobot_hmi.service.access.users import Role, UsersError, UsersFile
    from cobot_hmi.service.service_settings import SettingsError

    try:
        settings = hmi_settings(args)
        role = Role.parse(args.role)
        days = args.expires_days
        if days is not None and not (math.isfinite(days) and days > 0):
            return _fail(f"--expires-days: a positive number of days, got {days}")
        secret = UsersFile(settings.web.users_path).add_token(
            args.name, role, expires_in_s=None if days is None else days * 86400.0
        )
    except (SettingsError, UsersError) as error:
        return _fail(str(error))
    lifetime = "until revoked" if days is None else f"for {days:g} days"
    print(
        f"token:{args.name}: {role.label} {lifetime}, in {settings.web.users_path}", file=sys.stderr
    )
    print(secret)  # alone on stdout, for scripts
    return 0


def _users_revoke(args: argparse.Namespace) -> int:
    from cobot_hmi.cli.hmi_settings import hmi_settings
    from cobot_hmi.service.access.users import UsersError, UsersFile
    from cobot_hmi.service.service_settings import SettingsError

    try:
        settings = hmi_settings(args)
        UsersFile(settings.web.users_path).revoke_token(args.name)
    except (SettingsError, UsersError) as error:
        return _fail(str(error))
    print(f"token:{args.name}: revoked", file=sys.stderr)
    return 0

"""Verbs of the backend service: ``serve``, ``demo`` and ``users``.

``serve`` runs the service against a robot (or an emulator). ``demo`` starts the emulator as
its own process at 127.0.0.2 and the service against it on http://127.0.0.1:8000 with a fresh
operator password; Ctrl-C stops the service first (Forward Close while the robot still
listens), then the emulator. ``users add`` manages the users file; ``users token`` and
``revoke`` its long-lived API tokens.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import getpass
import math
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Final

DEMO_ROBOT_HOST: Final = "127.0.0.2"
DEMO_HTTP_HOST: Final = "127.0.0.1"
DEMO_HTTP_PORT: Final = 8000
DEMO_USER: Final = "operator"


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    from cobot_hmi.service.settings import add_arguments

    serve = subparsers.add_parser(
        "serve",
        help="run the web service against a robot (REST, WebSocket, frontend)",
        description=(
            "Hold a class 1 connection to the robot and serve the HMI. Settings come from the "
            "flags, then COBOT_HMI_* environment variables, then a TOML file (--config)."
        ),
    )
    add_arguments(serve)
    serve.set_defaults(handler=_serve)

    demo = subparsers.add_parser(
        "demo",
        help="the emulator at 127.0.0.2 and the service on http://127.0.0.1:8000",
        description=(
            "Start the emulator as its own process and the service against it, serving the "
            "built frontend. Creates (or resets) the operator account and prints its password "
            "once. Ctrl-C stops both (the service sends its Forward Close first)."
        ),
    )
    demo.add_argument("--robot-host", default=DEMO_ROBOT_HOST, help="emulator address")
    demo.add_argument("--robot-tcp-port", type=int, default=44818, help="emulator TCP port")
    demo.add_argument("--robot-udp-port", type=int, default=2222, help="emulator UDP port")
    demo.add_argument("--control-port", type=int, default=None, help="emulator control API port")
    demo.add_argument("--local-host", default=DEMO_HTTP_HOST, help="address receiving T→O")
    demo.add_argument("--local-udp-port", type=int, default=2222, help="UDP port receiving T→O")
    demo.add_argument("--host", default=DEMO_HTTP_HOST, help="HTTP bind address")
    demo.add_argument("--port", type=int, default=DEMO_HTTP_PORT, help="HTTP port")
    demo.add_argument("--rpi-ms", type=float, default=10.0, help="RPI, ms")
    demo.add_argument("--state-dir", type=Path, default=None, help="users file and database")
    demo.add_argument("--frontend-dir", type=Path, default=None, help="built frontend")
    demo.set_defaults(handler=_demo)

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
    add_arguments(add, only=("state_dir", "users_file"))
    add.set_defaults(handler=_users_add)
    listing = users_verbs.add_parser("list", help="list users and roles")
    add_arguments(listing, only=("state_dir", "users_file"))
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
    add_arguments(token, only=("state_dir", "users_file"))
    token.set_defaults(handler=_users_token)
    revoke = users_verbs.add_parser("revoke", help="revoke the API token NAME")
    revoke.add_argument("name")
    add_arguments(revoke, only=("state_dir", "users_file"))
    revoke.set_defaults(handler=_users_revoke)


def _fail(reason: str) -> int:
    print(f"cobot-hmi: {reason}", file=sys.stderr)
    return 2


def _serve(args: argparse.Namespace) -> int:
    from cobot_hmi.service.server import prepare_process, serve
    from cobot_hmi.service.settings import SettingsError, settings_from_args

    try:
        settings = settings_from_args(args)
        settings.originator_settings()
    except SettingsError as error:
        return _fail(str(error))
    prepare_process()
    with contextlib.suppress(KeyboardInterrupt):  # uvicorn re-raises the signal it handled
        asyncio.run(serve(settings))
    return 0


def _users_add(args: argparse.Namespace) -> int:
    from cobot_hmi.service.settings import SettingsError, settings_from_args
    from cobot_hmi.service.users import Role, UsersError, UsersFile

    try:
        settings = settings_from_args(args)
        role = Role.parse(args.role)
        if args.password_stdin:
            password = sys.stdin.readline().rstrip("\r\n")
        else:
            password = getpass.getpass(f"password for {args.name}: ")
            if getpass.getpass("again: ") != password:
                return _fail("the passwords differ")
        user = UsersFile(settings.users_path).add(args.name, role, password)
    except (SettingsError, UsersError) as error:
        return _fail(str(error))
    print(f"{user.name}: {user.role.label} in {settings.users_path}")
    return 0


def _users_list(args: argparse.Namespace) -> int:
    from cobot_hmi.service.settings import SettingsError, settings_from_args
    from cobot_hmi.service.users import UsersError, UsersFile

    try:
        settings = settings_from_args(args)
        users_file = UsersFile(settings.users_path)
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
    from cobot_hmi.service.settings import SettingsError, settings_from_args
    from cobot_hmi.service.users import Role, UsersError, UsersFile

    try:
        settings = settings_from_args(args)
        role = Role.parse(args.role)
        days = args.expires_days
        if days is not None and not (math.isfinite(days) and days > 0):
            return _fail(f"--expires-days: a positive number of days, got {days}")
        secret = UsersFile(settings.users_path).add_token(
            args.name, role, expires_in_s=None if days is None else days * 86400.0
        )
    except (SettingsError, UsersError) as error:
        return _fail(str(error))
    lifetime = "until revoked" if days is None else f"for {days:g} days"
    print(f"token:{args.name}: {role.label} {lifetime}, in {settings.users_path}", file=sys.stderr)
    print(secret)  # alone on stdout, for scripts
    return 0


def _users_revoke(args: argparse.Namespace) -> int:
    from cobot_hmi.service.settings import SettingsError, settings_from_args
    from cobot_hmi.service.users import UsersError, UsersFile

    try:
        settings = settings_from_args(args)
        UsersFile(settings.users_path).revoke_token(args.name)
    except (SettingsError, UsersError) as error:
        return _fail(str(error))
    print(f"token:{args.name}: revoked", file=sys.stderr)
    return 0


# --------------------------------------------------------------------------- demo


def _wait_for_tcp(host: str, port: int, process: subprocess.Popen[bytes], timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if process.poll() is not None:
            return False
        try:
            with socket.create_connection((host, port), timeout=0.5):
                return True
        except OSError:
            time.sleep(0.1)
    return False


def _stop_process(process: subprocess.Popen[bytes], timeout_s: float = 5.0) -> None:
    if process.poll() is not None:
        return
    process.send_signal(signal.SIGINT)
    try:
        process.wait(timeout_s)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()


def _demo(args: argparse.Namespace) -> int:
    from cobot_hmi.service.server import prepare_process, serve
    from cobot_hmi.service.settings import SettingsError, load_settings
    from cobot_hmi.service.users import Role, UsersError, UsersFile, generate_password

    flags: dict[str, object] = {
        "robot_host": args.robot_host,
        "robot_tcp_port": args.robot_tcp_port,
        "local_host": args.local_host,
        "local_udp_port": args.local_udp_port,
        "host": args.host,
        "port": args.port,
        "rpi_ms": args.rpi_ms,
    }
    if args.state_dir is not None:
        flags["state_dir"] = args.state_dir
    if args.frontend_dir is not None:
        flags["frontend_dir"] = args.frontend_dir
    try:
        settings = load_settings(flags)
        if args.state_dir is None:
            settings = load_settings({**flags, "state_dir": settings.state_dir / "demo"})
        password = generate_password()
        UsersFile(settings.users_path).add(DEMO_USER, Role.OPERATOR, password)
    except (SettingsError, UsersError) as error:
        return _fail(str(error))

    command = [
        sys.executable,
        "-m",
        "cobot_hmi.cli",
        "emulator",
        "--host",
        args.robot_host,
        "--tcp-port",
        str(args.robot_tcp_port),
        "--udp-port",
        str(args.robot_udp_port),
        "--verbose",  # its connection log shows the Forward Close on Ctrl-C
    ]
    if args.control_port is not None:
        command += ["--control-port", str(args.control_port)]
    # Its own session: the terminal's Ctrl-C reaches only us, so the service can still send
    # its Forward Close to a live emulator before we stop it.
    emulator = subprocess.Popen(command, start_new_session=True, env=os.environ.copy())
    try:
        if not _wait_for_tcp(args.robot_host, args.robot_tcp_port, emulator, timeout_s=15):
            return _fail(f"the emulator did not start on {args.robot_host}:{args.robot_tcp_port}")
        url = f"http://{args.host}:{args.port}/"
        print(
            f"cobot-hmi demo: emulator at {args.robot_host}, HMI at {url}\n"
            f"  log in as {DEMO_USER!r} with password {password!r} (shown only now)\n"
            "  Ctrl-C stops both.",
            flush=True,
        )
        prepare_process()
        with contextlib.suppress(KeyboardInterrupt):
            asyncio.run(serve(settings))
    finally:
        _stop_process(emulator)
    print("cobot-hmi demo: stopped.", flush=True)
    return 0

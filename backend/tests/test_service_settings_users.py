"""The service's settings (flags > environment > TOML), users file, sessions and throttling."""

from __future__ import annotations

import argparse
import json
import os
import pty
import re
import select
import stat
import subprocess
import sys
import time
from pathlib import Path

import pytest

from cobot_hmi.service.access.auth import LoginThrottle, Session, Sessions
from cobot_hmi.service.access.users import (
    Role,
    User,
    UsersError,
    UsersFile,
    hash_password,
    verify_password,
)
from cobot_hmi.service.config.arguments import add_arguments, settings_from_args
from cobot_hmi.service.config.loading import load_settings
from cobot_hmi.service.service_settings import ServiceSettings, SettingsError


def _parse(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    return parser.parse_args(argv)


def test_defaults() -> None:
    settings = load_settings({}, environ={})
    assert settings.cell.rpi_ms == 10.0
    assert settings.cell.rpi_us == 10_000
    assert settings.cell.robots == []  # none until --robot, COBOT_HMI_ROBOT_HOST or [[robots]]
    assert settings.web.users_path == settings.web.state_dir / "users.json"


def test_precedence_flags_over_environment_over_toml(tmp_path: Path) -> None:
    config = tmp_path / "hmi.toml"
    config.write_text('rpi_ms = 4.0\nport = 9000\nrobot_host = "10.0.0.9"\ninput_only = true\n')
    environ = {"COBOT_HMI_PORT": "9100", "COBOT_HMI_INPUT_ONLY": "false"}
    args = _parse(["--config", str(config), "--port", "9200", "--robot", "127.0.0.9"])
    settings = settings_from_args(args, environ)
    assert settings.cell.rpi_ms == 4.0  # TOML only
    assert settings.web.port == 9200  # flag beats environment beats TOML
    assert settings.cell.robot_host == "127.0.0.9"
    assert settings.cell.input_only is False  # environment beats TOML
    without_flag = settings_from_args(_parse(["--config", str(config)]), environ)
    assert without_flag.web.port == 9100


def test_config_file_from_environment(tmp_path: Path) -> None:
    config = tmp_path / "hmi.toml"
    config.write_text("ws_batch_ms = 20\n")
    settings = load_settings({}, environ={"COBOT_HMI_CONFIG": str(config)})
    assert settings.stream.ws_batch_ms == 20.0


def test_composite_flags_and_booleans() -> None:
    args = _parse(["--instances", "1,2,3", "--sizes", "24,300", "--input-only", "--rpi-ms", "2"])
    settings = settings_from_args(args, {})
    assert (
        settings.cell.config_instance,
        settings.cell.o2t_instance,
        settings.cell.t2o_instance,
    ) == (1, 2, 3)
    assert (settings.cell.o2t_size, settings.cell.t2o_size) == (24, 300)
    assert settings.cell.input_only
    assert settings.cell.robots == []
    assert settings.cell.rpi_us == 2000
    assert not settings_from_args(
        _parse(["--no-input-only"]), {"COBOT_HMI_INPUT_ONLY": "1"}
    ).cell.input_only


@pytest.mark.parametrize(
    ("environ", "message"),
    [
        ({"COBOT_HMI_PORT": "eighty"}, "port (from COBOT_HMI_PORT): Input should be a valid int"),
        ({"COBOT_HMI_PORT": "70000"}, "port (from COBOT_HMI_PORT): Input should be less than or"),
        ({"COBOT_HMI_RPI_MS": "-1"}, "rpi_ms (from COBOT_HMI_RPI_MS): Input should be greater"),
        ({"COBOT_HMI_INPUT_ONLY": "maybe"}, "Input should be a valid boolean"),
    ],
)
def test_bad_values_are_named(environ: dict[str, str], message: str) -> None:
    with pytest.raises(SettingsError, match=re.escape(message)):
        load_settings({}, environ=environ)


def test_unknown_toml_key_and_bad_toml(tmp_path: Path) -> None:
    config = tmp_path / "bad.toml"
    config.write_text("rpi = 3\n")
    with pytest.raises(SettingsError, match="unknown setting 'rpi'"):
        load_settings({}, environ={}, config_file=config)
    config.write_text("rpi_ms = \n")
    with pytest.raises(SettingsError, match=r"bad\.toml"):
        load_settings({}, environ={}, config_file=config)
    with pytest.raises(SettingsError, match=r"missing\.toml"):
        load_settings({}, environ={}, config_file=tmp_path / "missing.toml")


def test_originator_settings_need_a_robot() -> None:
    with pytest.raises(SettingsError, match="no robot"):
        ServiceSettings().cell.originator_settings()


# --------------------------------------------------------------------------- users


def test_password_hashes_are_salted_and_verify() -> None:
    first, second = hash_password("correct horse"), hash_password("correct horse")
    assert first != second
    assert first.startswith("scrypt$")
    assert verify_password("correct horse", first)
    assert not verify_password("wrong horse", first)
    assert not verify_password("correct horse", "scrypt$garbage")
    assert not verify_password("correct horse", "md5$x$y$z$a$b")


def test_users_file_add_authenticate_and_reload(tmp_path: Path) -> None:
    path = tmp_path / "state" / "users.json"
    users = UsersFile(path)
    assert users.users() == []
    users.add("alice", Role.OPERATOR, "alice-password")
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    assert "alice-password" not in path.read_text()
    assert users.authenticate("alice", "alice-password") == User("alice", Role.OPERATOR)
    assert users.authenticate("alice", "wrong-password") is None
    assert users.authenticate("nobody", "alice-password") is None
    # Another process adds a user: picked up without a restart.
    UsersFile(path).add("bob", Role.VIEWER, "bob-password")
    assert [u.name for u in users.users()] == ["alice", "bob"]
    with pytest.raises(UsersError, match="exists"):
        users.add("bob", Role.ADMIN, "bob-password", replace=False)
    users.add("bob", Role.ADMIN, "new-bob-password")
    assert users.authenticate("bob", "new-bob-password") == User("bob", Role.ADMIN)


def test_users_file_rejects_bad_input(tmp_path: Path) -> None:
    users = UsersFile(tmp_path / "users.json")
    with pytest.raises(UsersError, match="user name"):
        users.add("no spaces", Role.VIEWER, "long-enough")
    with pytest.raises(UsersError, match="at least 8"):
        users.add("carol", Role.VIEWER, "short")
    with pytest.raises(UsersError, match="unknown role"):
        Role.parse("superuser")


def test_corrupt_users_file_keeps_last_good_table(tmp_path: Path) -> None:
    path = tmp_path / "users.json"
    users = UsersFile(path)
    users.add("alice", Role.OPERATOR, "alice-password")
    assert users.authenticate("alice", "alice-password") is not None
    path.write_text("{not json")
    with pytest.raises(UsersError, match="unreadable"):
        users.users()
    assert users.authenticate("alice", "alice-password") is not None


def _cli(*args: str, stdin: str = "") -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "cobot_hmi.cli", *args],
        input=stdin,
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )


def test_users_add_verb_with_password_stdin(tmp_path: Path) -> None:
    result = _cli(
        "users",
        "add",
        "dave",
        "--role",
        "admin",
        "--password-stdin",
        "--state-dir",
        str(tmp_path),
        stdin="dave-password\n",
    )
    assert result.returncode == 0, result.stderr
    assert "dave: admin" in result.stdout
    document = json.loads((tmp_path / "users.json").read_text())
    assert document["users"]["dave"]["role"] == "admin"
    assert UsersFile(tmp_path / "users.json").authenticate("dave", "dave-password") is not None
    listing = _cli("users", "list", "--state-dir", str(tmp_path))
    assert listing.stdout.strip() == "dave\tadmin"
    bad = _cli("users", "add", "eve", "--role", "root", "--password-stdin", stdin="x" * 9 + "\n")
    assert bad.returncode == 2
    assert "unknown role" in bad.stderr


# --------------------------------------------------------------------------- sessions


def test_sessions_expire_when_unused() -> None:
    ended: list[tuple[str, str]] = []
    sessions = Sessions(0.2, lambda s, reason: ended.append((s.user.name, reason)))
    session = sessions.create(User("alice", Role.OPERATOR))
    assert sessions.get(session.token) is session
    assert sessions.get("not-a-token") is None
    time.sleep(0.25)
    assert sessions.sweep() == 1
    assert sessions.get(session.token) is None
    assert ended == [("alice", "session expired")]


def test_session_use_renews_it_and_logout_ends_it() -> None:
    ended: list[Session] = []
    sessions = Sessions(0.3, lambda s, _: ended.append(s))
    session = sessions.create(User("alice", Role.OPERATOR))
    for _ in range(4):
        # Each use moves the idle deadline a whole TTL past it (checked on the deadline, not by
        # sleeping in between: a busy machine may pause this thread longer than the TTL).
        used_at = time.monotonic()
        assert sessions.get(session.token, renew=True) is session
        assert session.expires_at_mono >= used_at + 0.3
    sessions.end(session, "logged out")
    sessions.end(session, "logged out")  # twice: reported once
    assert ended == [session]
    assert len(sessions) == 0


def test_login_throttle_slows_repeated_failures() -> None:
    throttle = LoginThrottle(free_attempts=2, max_delay_s=4.0)
    alice = ("alice", "127.0.0.1")
    throttle.failed(*alice)
    assert throttle.retry_after_s(*alice) == 0
    throttle.failed(*alice)
    assert 0.9 < throttle.retry_after_s(*alice) <= 1.0
    throttle.failed(*alice)
    assert 1.9 < throttle.retry_after_s(*alice) <= 2.0
    for _ in range(5):
        throttle.failed(*alice)
    assert throttle.retry_after_s(*alice) <= 4.0
    # Another user from the same address is slowed too (the address key), a fresh one is not.
    assert throttle.retry_after_s("bob", "127.0.0.1") > 0
    assert throttle.retry_after_s("bob", "127.0.0.2") == 0
    throttle.succeeded(*alice)
    # A success clears the user name's count, not the address's.
    assert throttle.retry_after_s("alice", "127.0.0.9") == 0
    assert throttle.retry_after_s(*alice) > 0


def test_login_throttle_bounds_what_one_address_does_to_a_user() -> None:
    throttle = LoginThrottle(free_attempts=2, max_delay_s=600.0, user_max_delay_s=2.0)
    for _ in range(12):  # a guesser at 10.0.0.66, failing for alice again and again
        throttle.failed("alice", "10.0.0.66")
    assert throttle.retry_after_s("mallory", "10.0.0.66") > 500  # the guesser's address waits
    assert 0 < throttle.retry_after_s("alice", "10.0.0.7") <= 2.0  # alice, elsewhere, briefly
    assert throttle.retry_after_s("bob", "10.0.0.7") == 0


def _on_a_terminal(args: list[str], dialogue: list[tuple[str, str]]) -> tuple[int, str]:
    """Run ``cobot-hmi ARGS`` on a pseudo-terminal; answer each (prompt, answer) in turn."""
    pid, fd = pty.fork()
    if pid == 0:  # the child: exec at once
        os.execv(sys.executable, [sys.executable, "-m", "cobot_hmi.cli", *args])
    output = b""
    answered = 0
    try:
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            ready, _, _ = select.select([fd], [], [], 0.5)
            if not ready:
                continue
            try:
                chunk = os.read(fd, 1024)
            except OSError:  # the child closed the terminal
                break
            if not chunk:
                break
            output += chunk
            if answered < len(dialogue) and output.count(dialogue[answered][0].encode()) > sum(
                1 for prompt, _ in dialogue[:answered] if prompt == dialogue[answered][0]
            ):
                os.write(fd, dialogue[answered][1].encode() + b"\n")
                answered += 1
    finally:
        os.close(fd)
        _, status = os.waitpid(pid, 0)
    return os.waitstatus_to_exitcode(status), output.decode(errors="replace")


def test_users_add_verb_prompts_twice(tmp_path: Path) -> None:
    args = ["users", "add", "erin", "--role", "viewer", "--state-dir", str(tmp_path)]
    prompt = "password for erin:"
    code, output = _on_a_terminal(args, [(prompt, "erin-password"), ("again:", "erin-password")])
    assert code == 0, output
    assert "password for erin:" in output
    assert "erin-password" not in output  # not echoed
    assert UsersFile(tmp_path / "users.json").authenticate("erin", "erin-password") is not None
    code, output = _on_a_terminal(args, [(prompt, "erin-password"), ("again:", "different-one")])
    assert code == 2
    assert "the passwords differ" in output

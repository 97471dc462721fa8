"""The service's settings: robots from ``[[robots]]``, the environment or the ``--robot``
shortcut; precedence flags > environment > TOML; errors that name the setting and its source;
connection settings declared once (``cobot_hmi.connection_params``)."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import pytest

from cobot_hmi import connection_params as cp
from cobot_hmi.cli import main
from cobot_hmi.service.config.arguments import add_arguments, settings_from_args
from cobot_hmi.service.config.loading import load_settings
from cobot_hmi.service.service_settings import RobotSettings, ServiceSettings, SettingsError

CELL = """
rpi_ms = 20
timeout_multiplier = 4

[[robots]]
name = "left"
host = "10.0.0.11"

[[robots]]
name = "right"
host = "10.0.0.12"
tcp_port = 44819
mode = "input-only"
rpi_ms = 8
t2o_size = 300
"""


def _parse(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    return parser.parse_args(argv)


def _config(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "hmi.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_robots_from_toml_inherit_the_top_level_connection_settings(tmp_path: Path) -> None:
    settings = load_settings({}, environ={}, config_file=_config(tmp_path, CELL))
    left, right = settings.cell.robots
    assert (left.name, left.host, left.tcp_port, left.mode) == (
        "left",
        "10.0.0.11",
        44818,
        "exclusive-owner",
    )
    assert (left.rpi_ms, left.timeout_multiplier, left.t2o_size) == (20.0, 4, cp.T2O_SIZE.default)
    assert (right.tcp_port, right.mode, right.input_only) == (44819, "input-only", True)
    assert (right.rpi_ms, right.rpi_us, right.timeout_multiplier, right.t2o_size) == (
        8.0,
        8000,
        4,
        300,
    )
    assert settings.cell.default_robot is left
    originator = settings.cell.originator_settings(right)
    assert (originator.robot_host, originator.tcp_port, originator.input_only) == (
        "10.0.0.12",
        44819,
        True,
    )
    assert (originator.rpi_us, originator.t2o_size) == (8000, 300)


def test_precedence_flags_over_environment_over_toml(tmp_path: Path) -> None:
    config = _config(tmp_path, "port = 9000\n" + CELL)
    environ = {"COBOT_HMI_PORT": "9100", "COBOT_HMI_RPI_MS": "30"}
    # Environment beats TOML, also for the robots' inherited defaults (right keeps its own).
    settings = settings_from_args(_parse(["--config", str(config)]), environ)
    assert settings.web.port == 9100
    assert [r.rpi_ms for r in settings.cell.robots] == [30.0, 8.0]
    # A flag beats both.
    settings = settings_from_args(
        _parse(["--config", str(config), "--port", "9200", "--rpi-ms", "40"]), environ
    )
    assert settings.web.port == 9200
    assert [r.rpi_ms for r in settings.cell.robots] == [40.0, 8.0]


def test_the_robot_list_comes_whole_from_the_highest_source(tmp_path: Path) -> None:
    config = _config(tmp_path, CELL)
    robots_json = '[{"name": "solo", "host": "10.0.0.21", "rpi_ms": 4}]'
    from_env = load_settings({}, {"COBOT_HMI_ROBOTS": robots_json}, config)
    assert [(r.name, r.host, r.rpi_ms) for r in from_env.cell.robots] == [
        ("solo", "10.0.0.21", 4.0)
    ]
    shortcut_env = load_settings({}, {"COBOT_HMI_ROBOT_HOST": "10.0.0.31"}, config)
    assert [(r.name, r.host) for r in shortcut_env.cell.robots] == [("robot", "10.0.0.31")]
    flags = settings_from_args(
        _parse(["--config", str(config), "--robot", "10.0.0.41", "--robot-name", "bench"]),
        {"COBOT_HMI_ROBOTS": robots_json},
    )
    assert [(r.name, r.host, r.rpi_ms) for r in flags.cell.robots] == [("bench", "10.0.0.41", 20.0)]


def test_the_one_robot_shortcut() -> None:
    args = _parse(["--robot", "127.0.0.9", "--input-only", "--instances", "1,2,3", "--rpi-ms", "2"])
    (robot,) = settings_from_args(args, {}).cell.robots
    assert (robot.name, robot.host, robot.mode, robot.rpi_us) == (
        "robot",
        "127.0.0.9",
        "input-only",
        2000,
    )
    assert (robot.config_instance, robot.o2t_instance, robot.t2o_instance) == (1, 2, 3)
    assert load_settings({}, environ={}).cell.robots == []
    with pytest.raises(SettingsError, match="no robot given"):
        load_settings({}, environ={}).cell.require_robots()


def test_replace_checks_again_and_robots_inherit_anew(tmp_path: Path) -> None:
    settings = load_settings({}, environ={}, config_file=_config(tmp_path, CELL))
    changed = settings.replace(rpi_ms=50.0)
    assert [r.rpi_ms for r in changed.cell.robots] == [50.0, 8.0]
    with pytest.raises(ValueError, match="greater than or equal to 1"):
        settings.replace(rpi_ms=0.1)


@pytest.mark.parametrize(
    ("toml", "message"),
    [
        (
            '[[robots]]\nname = "a"\nhost = "h"\nrpi = 3\n',
            "robots[0] (a).rpi (from config file {path}): unknown setting",
        ),
        ('[[robots]]\nhost = "h"\n', "robots[0].name (from config file {path}): Field required"),
        (
            '[[robots]]\nname = "Left Arm"\nhost = "h"\n',
            "robots[0] (Left Arm).name (from config file {path}): String should match pattern",
        ),
        (
            '[[robots]]\nname = "a"\nhost = "h"\nmode = "owner"\n',
            "robots[0] (a).mode (from config file {path}): Input should be 'exclusive-owner' or "
            "'input-only'",
        ),
        (
            '[[robots]]\nname = "a"\nhost = "h"\ntimeout_multiplier = 9\n',
            "robots[0] (a).timeout_multiplier (from config file {path}): Input should be less "
            "than or equal to 7",
        ),
        (
            '[[robots]]\nname = "a"\nhost = "h"\n[[robots]]\nname = "a"\nhost = "g"\n',
            "robots (from config file {path}): the name 'a' is given twice",
        ),
        (
            '[[robots]]\nname = "a"\nhost = "h"\n[[robots]]\nname = "b"\nhost = "h"\n',
            "robots (from config file {path}): 'a' and 'b' are both h:44818",
        ),
        ("robots = 3\n", "config file {path}: robots must be [[robots]] tables"),
        (
            'robot_host = "h"\n[[robots]]\nname = "a"\nhost = "g"\n',
            "config file {path}: give either robot_host or [[robots]], not both",
        ),
        ("rpi_ms = 0.5\n", "rpi_ms (from config file {path}): Input should be greater than"),
    ],
)
def test_robot_table_errors_are_clear(tmp_path: Path, toml: str, message: str) -> None:
    path = _config(tmp_path, toml)
    with pytest.raises(SettingsError, match=re.escape(message.format(path=path))):
        load_settings({}, environ={}, config_file=path)


def test_environment_errors_name_the_variable() -> None:
    with pytest.raises(SettingsError, match=re.escape("robots (from COBOT_HMI_ROBOTS): not valid")):
        load_settings({}, environ={"COBOT_HMI_ROBOTS": "[{"})
    with pytest.raises(SettingsError, match=re.escape("robot_name (from COBOT_HMI_ROBOT_NAME)")):
        load_settings({}, environ={"COBOT_HMI_ROBOT_HOST": "h", "COBOT_HMI_ROBOT_NAME": "A!"})
    with pytest.raises(SettingsError, match=re.escape("port (from --port)")):
        load_settings({"port": 70000}, environ={})


def test_connection_settings_are_declared_once() -> None:
    """The service's robot settings take default, bounds and help from connection_params, as
    the scanner's and the emulator's do."""
    fields = RobotSettings.model_fields
    for name, param in (
        ("tcp_port", cp.ENIP_TCP_PORT),
        ("timeout_multiplier", cp.TIMEOUT_MULTIPLIER),
        ("config_instance", cp.CONFIG_INSTANCE),
        ("o2t_instance", cp.O2T_INSTANCE),
        ("t2o_instance", cp.T2O_INSTANCE),
        ("heartbeat_instance", cp.HEARTBEAT_INSTANCE),
        ("o2t_size", cp.O2T_SIZE),
        ("t2o_size", cp.T2O_SIZE),
    ):
        info = fields[name]
        assert info.default == param.default, name
        assert info.description is not None and info.description.startswith(param.help)
        bounds = {type(m).__name__: m for m in info.metadata}
        assert bounds["Ge"].ge == param.minimum, name
        assert bounds["Le"].le == param.maximum, name
        with pytest.raises(ValueError, match=re.escape(param.range_text())):
            param.check(name, param.maximum + 1)
    assert fields["rpi_ms"].default * 1000 == cp.RPI_US.default
    assert ServiceSettings.flat_fields()["local_udp_port"].default == cp.CLASS1_UDP_PORT.default


def test_every_flag_names_its_environment_variable(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["serve", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for name in ("COBOT_HMI_ROBOT_HOST", "COBOT_HMI_ROBOT_NAME", "COBOT_HMI_RPI_MS"):
        assert name in text
    assert "--robot ROBOT_HOST" in text and "--robot-name ROBOT_NAME" in text


def test_serve_without_a_robot_says_so(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    for name in ("COBOT_HMI_ROBOT_HOST", "COBOT_HMI_ROBOTS", "COBOT_HMI_CONFIG"):
        monkeypatch.delenv(name, raising=False)
    assert main(["serve"]) == 2
    assert "no robot given" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("entry", "why"),
    [
        ("10.0.0.300", "not an IP address or network"),
        ("10.0.0.1/24", "has host bits set"),
        ("proxy.example", "not an IP address or network"),
        ("10.0.0.0/33", "not an IP address or network"),
        ("*", "trusting every peer is not offered"),
    ],
)
def test_trusted_proxies_refuses_malformed_entries_naming_them(
    tmp_path: Path, entry: str, why: str
) -> None:
    # uvicorn would take each of these as a literal that no peer matches: trusted nobody, silently.
    good = "10.0.0.1"
    from_env = {"COBOT_HMI_ROBOT_HOST": "h", "COBOT_HMI_TRUSTED_PROXIES": f"{good}, {entry}"}
    with pytest.raises(SettingsError) as error:
        load_settings({}, environ=from_env)
    message = str(error.value)
    assert f"trusted_proxies (from COBOT_HMI_TRUSTED_PROXIES): entry {entry!r}: " in message
    assert why in message
    path = _config(tmp_path, f'robot_host = "h"\ntrusted_proxies = ["{good}", "{entry}"]\n')
    with pytest.raises(SettingsError) as error:
        load_settings({}, environ={}, config_file=path)
    message = str(error.value)
    assert f"trusted_proxies (from config file {path}): entry {entry!r}: " in message
    assert why in message


def test_trusted_proxies_accepts_addresses_and_networks_in_canonical_form() -> None:
    settings = load_settings(
        {},
        environ={
            "COBOT_HMI_ROBOT_HOST": "h",
            "COBOT_HMI_TRUSTED_PROXIES": "127.0.0.1, 10.1.0.0/16,0:0::1, fd00::/8",
        },
    )
    assert settings.web.trusted_proxies == ["127.0.0.1", "10.1.0.0/16", "::1", "fd00::/8"]


def test_serve_with_a_malformed_trusted_proxy_does_not_start(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    for name in ("COBOT_HMI_ROBOT_HOST", "COBOT_HMI_ROBOTS", "COBOT_HMI_CONFIG"):
        monkeypatch.delenv(name, raising=False)
    assert main(["serve", "--robot", "127.0.0.1", "--trusted-proxies", "10.0.0.1/8"]) == 2
    err = capsys.readouterr().err
    assert "trusted_proxies (from --trusted-proxies): entry '10.0.0.1/8'" in err

"""The settings are nested, one part per concern, and every flat key still works: each key of
every part of ``serve``'s and the plant's settings (taken from the models, so a new setting is
covered without a word here) reaches its part from a flag, from ``COBOT_HMI_<NAME>`` and from
a TOML file, flat or in its part's table; an old flat settings file loads; an unknown key is
refused by name; and no part is built with the whole settings."""

from __future__ import annotations

import argparse
import importlib
import inspect
import json
import pkgutil
import re
from pathlib import Path
from typing import Any

import pytest
from pydantic import BaseModel, SecretStr

import cobot_hmi
from cobot_hmi.plant.plant_settings import PlantSettings
from cobot_hmi.service.config.arguments import add_arguments, settings_from_args
from cobot_hmi.service.config.loading import env_name, load_settings
from cobot_hmi.service.service_settings import ServiceSettings, SettingsError
from cobot_hmi.settings import HmiSettings

KEYS = HmiSettings.setting_keys()
CLASSES: dict[str, type[ServiceSettings]] = {"serve": HmiSettings, "plant": PlantSettings}
CASES = [("serve", name) for name in KEYS] + [
    ("plant", name) for name, part in PlantSettings.setting_keys().items() if part == "plant"
]
"""Every key of ``serve``'s settings and those the plant adds: (the command's, key)."""
DEFAULTS = {
    (command, name): CLASSES[command].flat_fields()[name].get_default(call_default_factory=True)
    for command, name in CASES
}
# The robot list comes from the source that names robots: an empty one names none.
DEFAULTS |= {
    ("serve", "robot_host"): "10.0.0.9",
    ("serve", "robots"): [{"name": "a", "host": "10.0.0.8"}],
}
GIVEN = sorted(case for case, value in DEFAULTS.items() if value is not None)
"""Keys with a value to give (a key whose default is "none" has no TOML form)."""


def _plain(value: Any) -> Any:
    """A setting's value as TOML and JSON hold it (a robot: the keys its table gave)."""
    if isinstance(value, SecretStr):
        return value.get_secret_value()
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, BaseModel):
        return value.model_dump(mode="json", exclude_unset=True)
    if isinstance(value, list):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    return value


def _toml_value(value: Any) -> str:
    value = _plain(value)
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, dict):
        return (
            "{" + ", ".join(f"{json.dumps(k)} = {_toml_value(v)}" for k, v in value.items()) + "}"
        )
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    return json.dumps(value)


def _reached(settings: ServiceSettings, name: str) -> Any:
    """The key's value in its part, which must have been given it (not defaulted)."""
    part_name = settings.setting_keys()[name]
    part = getattr(settings, part_name)
    assert name in part.model_fields_set, f"{name} did not reach the part {part_name}"
    return _plain(getattr(part, name))


def _config(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "hmi.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_every_key_is_in_exactly_one_part() -> None:
    parts = HmiSettings.parts()
    assert set(parts) >= {"web", "tls", "directory", "alarm_limits", "recording", "kiosk"}
    assert set(parts) >= {"cell", "site", "sparkplug", "opcua"}
    owners: dict[str, list[str]] = {}
    for part_name, model in parts.items():
        for name in model.model_fields:
            owners.setdefault(name, []).append(part_name)
    assert {name: [KEYS[name]] for name in KEYS} == owners
    assert not set(KEYS) & set(parts), "a key must not be called as a part"
    assert set(PlantSettings.setting_keys()) >= set(ServiceSettings.setting_keys())


@pytest.mark.parametrize(("command", "name"), CASES)
def test_every_key_is_routed_to_its_part(command: str, name: str) -> None:
    marker = object()
    settings_class = CLASSES[command]
    routed = settings_class.route_keys({name: marker})
    assert routed == {settings_class.setting_keys()[name]: {name: marker}}


@pytest.mark.parametrize(("command", "name"), CASES)
def test_every_key_reaches_its_part_from_a_flag(command: str, name: str) -> None:
    value = DEFAULTS[command, name]
    settings = load_settings({name: value}, {}, None, CLASSES[command])
    assert _reached(settings, name) == _plain(value)


@pytest.mark.parametrize(("command", "name"), GIVEN)
def test_every_key_reaches_its_part_from_the_environment(command: str, name: str) -> None:
    value = _plain(DEFAULTS[command, name])
    if isinstance(value, bool):
        text = "true" if value else "false"
    elif isinstance(value, (list, dict)) and name not in ("robots", "alarms"):
        text = _env_text(name, value)
    elif isinstance(value, (list, dict)):
        text = json.dumps(value)
    else:
        text = str(value)
    settings = load_settings({}, {env_name(name): text}, None, CLASSES[command])
    assert _reached(settings, name) == value


def _env_text(name: str, value: list[Any] | dict[str, Any]) -> str:
    """A list or table key's text as its variable takes it (``a,b``; ``K=V,…``; JSON)."""
    if isinstance(value, list):
        return ",".join(value)
    if name == "ldap_group_role":
        return json.dumps(value)
    return ",".join(f"{k}={v}" for k, v in value.items())


@pytest.mark.parametrize(("command", "name"), GIVEN)
def test_every_key_reaches_its_part_from_a_flat_or_a_nested_toml_key(
    command: str, name: str, tmp_path: Path
) -> None:
    settings_class, given = CLASSES[command], DEFAULTS[command, name]
    value = _toml_value(given)
    flat = load_settings({}, {}, _config(tmp_path, f"{name} = {value}\n"), settings_class)
    assert _reached(flat, name) == _plain(given)
    table = f"[{settings_class.setting_keys()[name]}]\n{name} = {value}\n"
    nested = load_settings({}, {}, _config(tmp_path, table), settings_class)
    assert _reached(nested, name) == _plain(given)


@pytest.mark.parametrize(
    ("command", "name"), [case for case in CASES if case[1] not in ("robots", "alarms")]
)
def test_every_key_but_the_tables_has_its_flag(command: str, name: str) -> None:
    parser = argparse.ArgumentParser()
    add_arguments(parser, settings_class=CLASSES[command])
    flags = [a for a in parser._actions if a.dest == name]
    assert len(flags) == 1, name
    assert env_name(name) in str(flags[0].help)


OLD_FILE = """
port = 9001
state_dir = "{state}"
view_requires_login = true
history_retention_days = 3.5
alarm_gap_rate_per_min = 4.0
kiosk_plot_window_s = 60.0
ldap_timeout_s = 9.0
mqtt_url = "mqtt://127.0.0.1:1883"
opcua_monitoring_hz = 5.0
time_zone = "UTC"
rpi_ms = 20
cycle_trigger = "controlbox_do.2:rising"

[[robots]]
name = "left"
host = "10.0.0.11"

[[alarms]]
name = "door"
field = "controlbox_di"
index = 1
active_when = true
robot = "left"
"""


def test_an_old_flat_settings_file_loads_into_the_parts(tmp_path: Path) -> None:
    path = _config(tmp_path, OLD_FILE.format(state=tmp_path))
    settings = load_settings({}, {}, path, HmiSettings)
    assert (settings.web.port, settings.web.state_dir) == (9001, tmp_path)
    assert settings.web.view_requires_login
    assert settings.recording.history_retention_days == 3.5
    assert settings.alarm_limits.alarm_gap_rate_per_min == 4.0
    assert [a.name for a in settings.alarm_limits.alarms] == ["door"]
    assert settings.kiosk.kiosk_plot_window_s == 60.0
    assert settings.directory.ldap_timeout_s == 9.0
    assert settings.sparkplug.mqtt_url == "mqtt://127.0.0.1:1883"
    assert settings.opcua.opcua_monitoring_hz == 5.0
    assert settings.site.time_zone == "UTC"
    (left,) = settings.cell.robots
    assert (left.rpi_ms, left.cycle_trigger) == (20.0, "controlbox_do.2:rising")
    assert settings.history_path == tmp_path / "history"
    # The precedence is the flat keys': the environment beats the file, a flag beats both.
    environ = {"COBOT_HMI_PORT": "9002", "COBOT_HMI_HISTORY_RETENTION_DAYS": "2"}
    loaded = load_settings({"history_retention_days": 1.0}, environ, path, HmiSettings)
    assert (loaded.web.port, loaded.recording.history_retention_days) == (9002, 1.0)


def test_a_part_as_a_table(tmp_path: Path) -> None:
    text = (
        'robot_host = "10.0.0.5"\n'
        "[recording]\nhistory_retention_days = 3\nhistory = false\n"
        "[web]\nport = 9003\n"
        "[alarm_limits]\nalarm_shelve_max_high_s = 60.0\n"
    )
    settings = load_settings({"port": 9004}, {}, _config(tmp_path, text), HmiSettings)
    assert settings.recording.history_retention_days == 3
    assert not settings.recording.history
    assert settings.web.port == 9004  # the flag beats the file's table
    assert settings.alarm_limits.alarm_shelve_max_high_s == 60.0
    assert [r.host for r in settings.cell.robots] == ["10.0.0.5"]
    # Built directly: a part given whole, a flat key beside it wins.
    direct = HmiSettings.from_keys(web={"port": 9005, "host": "127.0.0.2"}, port=9006)
    assert (direct.web.host, direct.web.port) == ("127.0.0.2", 9006)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("rpi = 3\n", "config file {path}: unknown setting 'rpi'"),
        (
            "[recording]\nretention = 3\n",
            "config file {path}: unknown setting recording.'retention'",
        ),
        ("[recording]\nport = 3\n", "config file {path}: unknown setting recording.'port'"),
        ("[nothing]\nport = 3\n", "config file {path}: unknown setting 'nothing'"),
    ],
)
def test_an_unknown_key_in_a_file_is_refused_by_name(
    tmp_path: Path, text: str, message: str
) -> None:
    path = _config(tmp_path, text)
    with pytest.raises(SettingsError, match=re.escape(message.format(path=path))):
        load_settings({}, {}, path, HmiSettings)


def test_an_unknown_key_elsewhere_is_refused_by_name() -> None:
    with pytest.raises(SettingsError, match=re.escape("unknown setting 'rpi'")):
        load_settings({"rpi": 3}, {}, None, HmiSettings)
    with pytest.raises(ValueError, match="rpi"):
        HmiSettings.from_keys(rpi=3)
    with pytest.raises(ValueError, match="retention"):
        HmiSettings.from_keys(recording={"retention": 3})
    with pytest.raises(ValueError, match="rpi"):
        HmiSettings.from_keys(robot_host="h").replace(rpi=3)


def test_errors_name_the_flat_key_and_its_source() -> None:
    with pytest.raises(SettingsError, match=re.escape("history_retention_days (from --history")):
        load_settings({"history_retention_days": -1}, {}, None, HmiSettings)
    environ = {"COBOT_HMI_OPCUA_MONITORING_HZ": "0"}
    with pytest.raises(SettingsError, match=re.escape("opcua_monitoring_hz (from COBOT_HMI_")):
        load_settings({}, environ, None, HmiSettings)


def test_flags_reach_the_parts() -> None:
    parser = argparse.ArgumentParser()
    add_arguments(parser, settings_class=HmiSettings)
    args = parser.parse_args(
        ["--robot", "10.0.0.7", "--no-history", "--opcua-writes", "--shift-starts", "07:00"]
    )
    settings = settings_from_args(args, {}, HmiSettings)
    assert [r.host for r in settings.cell.robots] == ["10.0.0.7"]
    assert not settings.recording.history and settings.opcua.opcua_writes
    assert settings.kiosk.shift_starts == ["07:00"]


# --------------------------------------------------------------------------- no part gets the whole

COMPOSITION_ROOTS = {"Service", "PlantRuntime"}
"""What is built with the whole settings and hands each part its own."""


def _constructors() -> list[tuple[str, inspect.Signature]]:
    found = []
    for info in pkgutil.walk_packages(cobot_hmi.__path__, "cobot_hmi."):
        if info.name.endswith("__main__"):
            continue
        module = importlib.import_module(info.name)
        for name, value in vars(module).items():
            if inspect.isclass(value) and value.__module__ == module.__name__:
                if issubclass(value, BaseModel) or "__init__" not in vars(value):
                    continue
                found.append((f"{module.__name__}.{name}", inspect.signature(value.__init__)))
    return found


def test_no_part_is_built_with_the_whole_settings() -> None:
    constructors = _constructors()
    names = {name.rsplit(".", 1)[1] for name, _ in constructors}
    for part in ("Recorder", "RobotRuntime", "AlarmEngine", "ServiceFeed", "EdgeNode"):
        assert part in names
    assert {"OpcUaServer", "Directory", "OpcUaExtension"} <= names
    whole = re.compile(r"\b(ServiceSettings|HmiSettings|PlantSettings)\b")
    given_whole = sorted(
        name
        for name, signature in constructors
        if name.rsplit(".", 1)[1] not in COMPOSITION_ROOTS
        and any(
            whole.search(str(p.annotation)) and not str(p.annotation).startswith("type[")
            for p in signature.parameters.values()
        )
    )
    assert given_whole == [], f"built with the whole settings: {given_whole}"

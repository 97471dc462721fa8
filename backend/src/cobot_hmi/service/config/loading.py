"""Layer: service. Loading the settings: defaults < TOML file < environment < flags, one
checked settings object (``ServiceSettings`` or a class composed above the service with more
parts, ``cobot_hmi.settings.HmiSettings``: ``settings_class``); errors name their source.

Every source speaks the flat keys (``ServiceSettings.flat_fields``); a TOML file may also give
a part as a table (``[recording]``), read as its flat keys. The layers are merged key by key,
and the settings class routes each key to its part."""

from __future__ import annotations

import os
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Final, TypeVar, overload

from pydantic import ValidationError, create_model
from pydantic_settings import BaseSettings, EnvSettingsSource, SettingsConfigDict
from pydantic_settings import SettingsError as PydanticSettingsError
from pydantic_settings.sources.utils import parse_env_vars

from cobot_hmi.service.service_settings import ServiceSettings
from cobot_hmi.service.setting_fields import CONFIG_ENV, ENV_PREFIX, SettingsError

# --------------------------------------------------------------------------- loading

SettingsT = TypeVar("SettingsT", bound=ServiceSettings)

_ROBOT_GROUP: Final = ("robots", "robot_host")
"""Settings that together say which robots there are: taken from one source only."""


def env_name(name: str) -> str:
    return ENV_PREFIX + name.upper()


class _FlatKeys(BaseSettings):
    model_config = SettingsConfigDict(env_prefix=ENV_PREFIX, case_sensitive=False)


_FLAT_VIEWS: dict[type[ServiceSettings], type[BaseSettings]] = {}


def _flat_view(settings_class: type[ServiceSettings]) -> type[BaseSettings]:
    """A settings class of the flat keys alone (each key's declaration, no parts): what
    pydantic-settings' environment source reads ``COBOT_HMI_<NAME>`` into, decoding a list or
    a table from JSON as the key's type asks."""
    view = _FLAT_VIEWS.get(settings_class)
    if view is None:
        fields: dict[str, Any] = {
            name: (info.annotation, info) for name, info in settings_class.flat_fields().items()
        }
        view = create_model(f"{settings_class.__name__}Keys", __base__=_FlatKeys, **fields)
        _FLAT_VIEWS[settings_class] = view
    return view


class _EnvironSource(EnvSettingsSource):
    """pydantic-settings' environment source, over a given mapping instead of ``os.environ``."""

    def __init__(self, environ: Mapping[str, str], settings_class: type[ServiceSettings]) -> None:
        self._environ = environ
        super().__init__(_flat_view(settings_class))

    def _load_env_vars(self) -> Mapping[str, str | None]:
        return parse_env_vars(dict(self._environ), self.case_sensitive, self.env_ignore_empty, None)


def _toml_layer(path: Path, settings_class: type[ServiceSettings]) -> dict[str, Any]:
    """The file's flat keys: top-level keys, and the keys of a part's table (``[recording]``)."""
    where = f"config file {path}"
    try:
        document = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as error:
        raise SettingsError(f"{where}: {error.strerror}") from None
    except tomllib.TOMLDecodeError as error:
        raise SettingsError(f"{where}: {error}") from None
    keys, parts = settings_class.setting_keys(), settings_class.parts()
    data: dict[str, Any] = {}
    for key, value in document.items():
        if key in parts and isinstance(value, dict):
            for name, inner in value.items():
                if keys.get(name) != key:
                    raise SettingsError(f"{where}: unknown setting {key}.{name!r}")
                data[name] = inner
        elif key in keys:
            data[key] = value
        else:
            raise SettingsError(f"{where}: unknown setting {key!r}")
    robots = data.get("robots")
    if robots is not None and not (
        isinstance(robots, list) and all(isinstance(r, dict) for r in robots)
    ):
        raise SettingsError(f"{where}: robots must be [[robots]] tables")
    return data


def _environment_layer(
    environ: Mapping[str, str], settings_class: type[ServiceSettings]
) -> dict[str, Any]:
    try:
        return dict(_EnvironSource(environ, settings_class)())
    except PydanticSettingsError as error:
        # A complex value (COBOT_HMI_ROBOTS) that is not JSON.
        field = str(error).split('"')[1] if '"' in str(error) else "?"
        cause = error.__cause__ or error
        raise SettingsError(f"{field} (from {env_name(field)}): not valid JSON: {cause}") from None


@overload
def load_settings(
    flags: Mapping[str, object] | None = None,
    environ: Mapping[str, str] | None = None,
    config_file: Path | None = None,
) -> ServiceSettings: ...


@overload
def load_settings(
    flags: Mapping[str, object] | None,
    environ: Mapping[str, str] | None,
    config_file: Path | None,
    settings_class: type[SettingsT],
) -> SettingsT: ...


def load_settings(
    flags: Mapping[str, object] | None = None,
    environ: Mapping[str, str] | None = None,
    config_file: Path | None = None,
    settings_class: type[ServiceSettings] = ServiceSettings,
) -> ServiceSettings:
    """Layer defaults < TOML file < environment < flags into one checked ``settings_class``.

    ``flags`` holds only what was given on the command line. The TOML file is ``config_file``
    if given, else ``$COBOT_HMI_CONFIG`` if set. The robot list (``[[robots]]``,
    ``COBOT_HMI_ROBOTS``, or the ``robot_host`` shortcut) comes whole from the highest source
    that names robots.
    """
    environ = os.environ if environ is None else environ
    path = config_file or (Path(environ[CONFIG_ENV]) if environ.get(CONFIG_ENV) else None)
    layers: list[tuple[str, dict[str, Any]]] = []  # lowest precedence first
    if path is not None:
        layers.append((f"config file {path}", _toml_layer(path, settings_class)))
    layers.append(("environment", _environment_layer(environ, settings_class)))
    flag_values = dict(flags or {})
    for name in flag_values:
        if name not in settings_class.setting_keys():
            raise SettingsError(f"unknown setting {name!r}")
    layers.append(("flags", flag_values))

    robot_layer = None
    for index, (source, values) in enumerate(layers):
        given = [key for key in _ROBOT_GROUP if values.get(key)]
        if len(given) > 1:
            where = _source_of(source, "robots", settings_class)
            raise SettingsError(f"{where}: give either robot_host or [[robots]], not both")
        if given:
            robot_layer = index
    merged: dict[str, Any] = {}
    sources: dict[str, str] = {}
    for index, (source, values) in enumerate(layers):
        for key, value in values.items():
            if key in _ROBOT_GROUP and index != robot_layer:
                continue
            merged[key] = value
            sources[key] = source
    try:
        return settings_class.model_validate(merged)
    except ValidationError as error:
        raise SettingsError(_describe(error, sources, merged, settings_class)) from None


def _source_of(source: str, name: str, settings_class: type[ServiceSettings]) -> str:
    if source == "environment":
        return env_name(name)
    if source == "flags":
        info = settings_class.flat_fields().get(name)
        extra = info.json_schema_extra if info is not None else None
        flag = extra.get("flag") if isinstance(extra, dict) else None
        return str(flag or "--" + name.replace("_", "-"))
    return source


def _describe(
    error: ValidationError,
    sources: Mapping[str, str],
    given: Mapping[str, Any],
    settings_class: type[ServiceSettings],
) -> str:
    """Each problem as ``field (from SOURCE): what, got VALUE``; robots by index and name."""
    lines = []
    parts = settings_class.parts()
    for problem in error.errors(include_url=False):
        location = problem["loc"]
        if location and location[0] in parts:  # a part's key is said as its flat key
            location = location[1:]
        message = str(problem["msg"]).removeprefix("Value error, ")
        if not location:
            if message.startswith("robots:"):
                source = _source_of(
                    sources.get("robots", sources.get("robot_host", "")), "robots", settings_class
                )
                message = f"robots (from {source}):" + message.removeprefix("robots:")
            lines.append(message)
            continue
        top = str(location[0])
        where = top
        rest = list(location[1:])
        first = rest[0] if rest else None
        if top == "robots" and isinstance(first, int):
            index = first
            rest.pop(0)
            where = f"robots[{index}]"
            robots = given.get("robots")
            if isinstance(robots, list) and index < len(robots) and isinstance(robots[index], dict):
                name = robots[index].get("name")
                if name is not None:
                    where += f" ({name})"
        if rest:
            where += "." + ".".join(str(part) for part in rest)
        source = _source_of(sources.get(top, "defaults"), top, settings_class)
        if problem["type"] == "extra_forbidden":
            message = "unknown setting"
        lines.append(f"{where} (from {source}): {message}, got {problem['input']!r}")
    return "; ".join(lines)

"""Layer: service. The command line of the settings: one flag per flat key, derived from the
parts' fields (``ServiceSettings.flat_fields``), and the settings from parsed flags."""

from __future__ import annotations

import argparse
import types
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any, overload

from cobot_hmi import connection_params as cp
from cobot_hmi.service.config.loading import SettingsT, env_name, load_settings
from cobot_hmi.service.service_settings import ServiceSettings
from cobot_hmi.service.setting_fields import O2T_SIZE, T2O_SIZE, SettingsError

# --------------------------------------------------------------------------- command line


def _flag_type(name: str, settings_class: type[ServiceSettings]) -> type:
    """The value type of a setting's flag (``Optional`` and ``Annotated`` stripped)."""
    hint: Any = settings_class.flat_fields()[name].annotation
    if isinstance(hint, types.UnionType) or typing.get_origin(hint) is typing.Union:
        hint = next(a for a in typing.get_args(hint) if a is not type(None))
    if typing.get_origin(hint) is list:
        return str  # a comma-separated list, split by the setting's validator
    return hint if hint in (bool, int, float, Path) else str


def add_arguments(
    parser: argparse.ArgumentParser,
    *,
    only: tuple[str, ...] | None = None,
    settings_class: type[ServiceSettings] = ServiceSettings,
) -> None:
    """One flag per setting of ``settings_class`` (``--rpi-ms``), absent from the namespace
    unless given.

    Also ``--config FILE``, ``--instances CFG,O2T,T2O`` and ``--sizes O2T,T2O`` as on
    ``cobot-hmi scan``. ``only`` limits the flags to some settings (the ``users`` verb).
    The robot list (``robots``) is for the TOML file or ``COBOT_HMI_ROBOTS``.
    """
    parser.add_argument("--config", type=Path, default=argparse.SUPPRESS, help="TOML file")
    for name, info in settings_class.flat_fields().items():
        if name in ("robots", "alarms") or (only is not None and name not in only):
            continue
        extra = info.json_schema_extra if isinstance(info.json_schema_extra, dict) else {}
        flag = str(extra.get("flag") or "--" + name.replace("_", "-"))
        kind = _flag_type(name, settings_class)
        default = info.get_default(call_default_factory=True)
        help_text = f"{info.description} (env {env_name(name)}; default {default})"
        if extra.get("repeatable"):  # --ldap-group-role A=x --ldap-group-role B=y
            parser.add_argument(
                flag,
                dest=name,
                action="append",
                default=argparse.SUPPRESS,
                metavar=name.upper(),
                help=help_text + "; repeatable",
            )
        elif kind is bool:
            parser.add_argument(
                flag,
                dest=name,
                action=argparse.BooleanOptionalAction,
                default=argparse.SUPPRESS,
                help=help_text,
            )
        else:
            parser.add_argument(
                flag,
                dest=name,
                type=kind,
                default=argparse.SUPPRESS,
                metavar=name.upper(),
                help=help_text,
            )
    if only is None:
        parser.add_argument(
            "--instances",
            default=argparse.SUPPRESS,
            metavar="CFG,O2T,T2O",
            help="assembly instances, e.g. "
            f"{cp.CONFIG_INSTANCE.default},{cp.O2T_INSTANCE.default},{cp.T2O_INSTANCE.default}",
        )
        parser.add_argument(
            "--sizes",
            default=argparse.SUPPRESS,
            metavar="O2T,T2O",
            help=f"e.g. {O2T_SIZE},{T2O_SIZE}",
        )


def _ints(text: str, count: int, what: str) -> list[int]:
    parts = text.split(",")
    if len(parts) != count:
        raise SettingsError(f"{what}: expected {count} comma-separated numbers, got {text!r}")
    try:
        return [int(p, 0) for p in parts]
    except ValueError:
        raise SettingsError(f"{what}: expected numbers, got {text!r}") from None


@overload
def settings_from_args(
    args: argparse.Namespace, environ: Mapping[str, str] | None = None
) -> ServiceSettings: ...


@overload
def settings_from_args(
    args: argparse.Namespace, environ: Mapping[str, str] | None, settings_class: type[SettingsT]
) -> SettingsT: ...


def settings_from_args(
    args: argparse.Namespace,
    environ: Mapping[str, str] | None = None,
    settings_class: type[ServiceSettings] = ServiceSettings,
) -> ServiceSettings:
    """``load_settings`` with the flags that ``add_arguments`` parsed into ``args``."""
    given = vars(args)
    flags = {name: given[name] for name in settings_class.setting_keys() if name in given}
    if "instances" in given:
        cfg, o2t, t2o = _ints(given["instances"], 3, "--instances")
        flags |= {"config_instance": cfg, "o2t_instance": o2t, "t2o_instance": t2o}
    if "sizes" in given:
        o2t_size, t2o_size = _ints(given["sizes"], 2, "--sizes")
        flags |= {"o2t_size": o2t_size, "t2o_size": t2o_size}
    return load_settings(flags, environ, given.get("config"), settings_class)

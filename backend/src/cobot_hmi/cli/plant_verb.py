"""Layer: entry point. ``cobot-hmi plant``: the plant's Sparkplug 3.0 host application and its
web API (``cobot_hmi.plant``; docs/operations.md "The plant").

Settings as ``serve`` reads them (flags, ``COBOT_HMI_*``, the TOML file): the service's login,
roles, TLS, directory and HTTP bounds, and the plant's ``--mqtt-url`` (repeatable), ``--group``
(repeatable), ``--plant-host-id`` and ``--peer`` (repeatable: the other plant processes whose
cells its page shows, a plant split by group). On a state directory whose users file has no
``operator`` yet, one is made and its password printed once.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import sys
from typing import Final

PLANT_USER: Final = "operator"
_SHARED: Final = frozenset(
    {
        "host",
        "port",
        "state_dir",
        "users_file",
        "database",
        "frontend_dir",
        "view_requires_login",
        "session_ttl_s",
        "cookie_secure",
        "max_body_bytes",
        "allowed_hosts",
        "allowed_origins",
        "trusted_proxies",
        "time_zone",
    }
)
"""The service's settings that mean the same for the plant (with its login, TLS, directory and
HTTP bounds): the robots' are not the plant's flags."""


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    from cobot_hmi.plant.plant_settings import PlantHostSettings, PlantSettings
    from cobot_hmi.service.config.arguments import add_arguments

    plant = subparsers.add_parser(
        "plant",
        help="every cell on one page: a Sparkplug host application on the plant's brokers",
        description=(
            "Subscribe to the Sparkplug namespace of the plant's brokers (--mqtt-url, "
            "repeatable: the next when one goes away; --group, repeatable: only those groups) "
            "as a Sparkplug 3.0 host application, record what arrives, and serve the plant's "
            "REST API with the same login, roles, TLS and directory options as serve; --peer "
            "URL, repeatable: the other plant processes whose cells its page shows as well."
        ),
    )
    from cobot_hmi.service.service_settings import ServiceSettings

    own = list(PlantHostSettings.model_fields)
    shared = [
        name
        for name in ServiceSettings.setting_keys()
        if name in _SHARED or name.startswith(("ldap_", "tls_", "http_", "login_", "anonymous_"))
    ]
    add_arguments(plant, only=(*own, *shared), settings_class=PlantSettings)
    plant.set_defaults(handler=_plant)


def _fail(reason: str) -> int:
    print(f"cobot-hmi: {reason}", file=sys.stderr)
    return 2


def _plant(args: argparse.Namespace) -> int:
    import uvicorn

    from cobot_hmi.plant.app import create_plant_app
    from cobot_hmi.plant.plant_settings import PlantSettings
    from cobot_hmi.plant.runtime import PlantRuntime
    from cobot_hmi.service.access.users import Role, UsersError, UsersFile, generate_password
    from cobot_hmi.service.api.server import prepare_process, uvicorn_config
    from cobot_hmi.service.api.tls import TlsError
    from cobot_hmi.service.config.arguments import settings_from_args
    from cobot_hmi.service.service_settings import SettingsError

    try:
        settings = settings_from_args(args, None, PlantSettings)
        if not settings.plant.mqtt_urls:
            raise SettingsError("the plant needs a broker: --mqtt-url mqtt://HOST:PORT")
        runtime = PlantRuntime(settings)
    except (SettingsError, ValueError) as error:
        return _fail(str(error))
    try:
        users = UsersFile(settings.web.users_path)
        if users.user(PLANT_USER) is None:
            password = generate_password()
            users.add(PLANT_USER, Role.OPERATOR, password)
            print(
                f"cobot-hmi plant: log in as {PLANT_USER!r} with password {password!r} "
                f"(shown only now; users file {settings.web.users_path})",
                flush=True,
            )
    except UsersError as error:
        return _fail(str(error))
    prepare_process()
    try:
        server = uvicorn.Server(
            uvicorn_config(create_plant_app(runtime), settings.web, settings.tls)
        )
        plant, web = settings.plant, settings.web
        print(
            f"cobot-hmi plant: host {plant.plant_host_id} on {', '.join(plant.mqtt_urls)}; "
            f"API at http{'s' if settings.tls.tls_enabled else ''}://{web.host}:{web.port}/",
            flush=True,
        )
        with contextlib.suppress(KeyboardInterrupt):
            asyncio.run(server.serve())
    except TlsError as error:
        return _fail(f"TLS: {error}")
    return 0

"""Layer: entry point. The HMI's settings for the verbs that read them, in one place: their flags
and the settings a verb's arguments give (``cobot_hmi.settings.HmiSettings``: the service's, the
OPC UA server's and the Sparkplug edge node's, as the composition root builds them). The verb
modules import this inside ``register`` and their handlers, so ``cobot-hmi --help`` stays fast.
"""

from __future__ import annotations

import argparse

from cobot_hmi.service.config.arguments import add_arguments, settings_from_args
from cobot_hmi.settings import HmiSettings


def add_hmi_arguments(parser: argparse.ArgumentParser, only: tuple[str, ...] | None = None) -> None:
    """One flag per HMI setting (``only``: some of them), as ``add_arguments`` makes them."""
    add_arguments(parser, only=only, settings_class=HmiSettings)


def hmi_settings(args: argparse.Namespace) -> HmiSettings:
    """The HMI's settings from a verb's flags, the environment and the TOML file."""
    return settings_from_args(args, None, HmiSettings)

"""Layer: entry point. The one command line, ``cobot-hmi <verb>``.

Each verb lives in a module of this package that exposes ``register(subparsers)``; the module
imports what it runs inside its handler, so ``cobot-hmi --help`` stays fast.
"""

from __future__ import annotations

import argparse
import importlib
import signal
import sys
from collections.abc import Callable, Sequence
from typing import Protocol, cast

from cobot_hmi import __version__
from cobot_hmi.cli.process_memory import limit_malloc_arenas

VERB_MODULES = (
    "cobot_hmi.cli.audit_verbs",
    "cobot_hmi.cli.codec_verbs",
    "cobot_hmi.cli.demo_verb",
    "cobot_hmi.cli.discovery_verbs",
    "cobot_hmi.cli.emulator_verb",
    "cobot_hmi.cli.health_verb",
    "cobot_hmi.cli.history_verbs",
    "cobot_hmi.cli.openapi_verb",
    "cobot_hmi.cli.plant_verb",
    "cobot_hmi.cli.scanner_verbs",
    "cobot_hmi.cli.service_verbs",
)
"""Modules whose ``register`` adds verbs; a new verb goes in one of them or in a new module."""


class _VerbModule(Protocol):
    def register(self, subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None: ...


Handler = Callable[[argparse.Namespace], int]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="cobot-hmi",
        description="Web HMI for a Doosan cobot over an EtherNet/IP class 1 connection.",
    )
    parser.add_argument("--version", action="version", version=f"cobot-hmi {__version__}")
    subparsers = parser.add_subparsers(dest="verb", required=True, metavar="VERB")
    for name in VERB_MODULES:
        cast(_VerbModule, importlib.import_module(name)).register(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    # Before any thread starts: the service's RSS stays flat across the recorder's closes.
    limit_malloc_arenas()
    args = build_parser().parse_args(argv)
    handler = cast(Handler, args.handler)
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        # Started with SIGINT ignored (a background job of a script, a test runner's worker):
        # Ctrl-C and ``kill -INT`` still stop the command, even before the service's own
        # handler is installed, instead of being lost and leaving it running.
        signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        return handler(args)
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())

"""Layer: entry point. The ``probe`` and ``scan`` verbs (originator side)."""

from __future__ import annotations

import argparse


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """The verbs arrive with the originator."""

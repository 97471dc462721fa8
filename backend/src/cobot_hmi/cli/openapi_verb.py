"""Verb ``openapi``: print or write the service's OpenAPI document without starting anything.

The committed copy (``docs/openapi.json``) is what the frontend's API types are generated from
(``make codegen``); ``--check`` fails when it differs from what the code describes, so a model
changed without regenerating is caught (a test runs it too).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path
from typing import Any, Final

DEFAULT_OUTPUT: Final = Path(__file__).resolve().parents[4] / "docs" / "openapi.json"
"""``docs/openapi.json`` of the repository this package is installed from (editable install)."""
PLANT_OUTPUT: Final = DEFAULT_OUTPUT.with_name("plant-openapi.json")
"""``docs/plant-openapi.json``: the plant's document (``--plant``), the plant page's types."""


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "openapi",
        help="print the service's OpenAPI document (or write / check a file)",
        description=(
            "Build the service's OpenAPI document (REST routes, error answers, WebSocket "
            "messages) without connecting to anything and print it, or write it to a file. "
            "--check compares the file with it and fails when it is stale."
        ),
    )
    parser.add_argument(
        "-o", "--output", type=Path, default=None, help="write to this file instead of stdout"
    )
    parser.add_argument(
        "--check",
        action="store_true",
        help=f"fail (exit 1) if the file (--output, default {DEFAULT_OUTPUT.name} in docs/) "
        "differs",
    )
    parser.add_argument(
        "--plant",
        action="store_true",
        help=f"the plant's document (cobot-hmi plant; default file {PLANT_OUTPUT.name} in docs/)",
    )
    parser.set_defaults(handler=_openapi)


def openapi_document() -> dict[str, Any]:
    """The document as the running service would serve it at ``/openapi.json``."""
    from cobot_hmi.composition import build_service
    from cobot_hmi.service.api.app import create_app
    from cobot_hmi.settings import HmiSettings

    # Nothing is opened or started: the service object only gives the routes their types.
    with tempfile.TemporaryDirectory(prefix="cobot-hmi-openapi-") as state:
        settings = HmiSettings.from_keys(robot_host="127.0.0.1", state_dir=Path(state))
        app = create_app(build_service(settings), manage_lifecycle=False)
        return app.openapi()


def render(plant: bool = False) -> str:
    """The document as committed: sorted keys, two-space indent, one trailing newline."""
    if plant:
        from cobot_hmi.plant.app import plant_openapi_document

        document = plant_openapi_document()
    else:
        document = openapi_document()
    return json.dumps(document, indent=2, sort_keys=True, ensure_ascii=False) + "\n"


def _openapi(args: argparse.Namespace) -> int:
    text = render(args.plant)
    if args.check:
        path: Path = args.output or (PLANT_OUTPUT if args.plant else DEFAULT_OUTPUT)
        current = path.read_text(encoding="utf-8") if path.is_file() else None
        if current != text:
            print(
                f"cobot-hmi openapi: {path} is stale; run: cobot-hmi openapi --output {path}",
                file=sys.stderr,
            )
            return 1
        print(f"{path}: up to date")
        return 0
    if args.output is None:
        sys.stdout.write(text)
        return 0
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(text, encoding="utf-8")
    print(f"wrote {args.output}")
    return 0

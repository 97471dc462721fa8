"""Layer: health (pure). Imports ``stored_format``.

The engine's whole state as one JSON document (baselines, recent cells, life, knocks, drift,
trend), so a consumer can save it anywhere (a file, a database row) and restore the engine
after a restart. It carries ``format_version`` (``StoredFormat``): a newer document than this
build reads is refused by name, never guessed at. The frames of a cycle in progress are not
kept: that one cycle is lost across a restart.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Final

from cobot_hmi.stored_format import StoredFormat

HEALTH_STATE_FORMAT: Final = StoredFormat("robot health state", 1)
KIND: Final = "cobot-hmi robot health"


def wrap(body: dict[str, object]) -> dict[str, object]:
    return {"kind": KIND, "format_version": HEALTH_STATE_FORMAT.version, **body}


def unwrap(document: Mapping[str, object], where: str = "health state") -> dict[str, object]:
    """The body of a document, its version checked (``FormatVersionError`` if newer)."""
    if document.get("kind") != KIND:
        raise ValueError(f"{where}: not a robot health state (kind {document.get('kind')!r})")
    HEALTH_STATE_FORMAT.read_version(document.get("format_version"), where)
    return {k: v for k, v in document.items() if k not in ("kind", "format_version")}

"""Layer: service. The bounds of the API's integer parameters, declared once: a page's offset and
size, a row's id. They are in the contract (OpenAPI ``minimum``/``maximum``), and a value
outside them is a 422 naming the parameter before any route or database work.

The ceiling of an offset or an id is ``MAX_INTEGER`` (2^53 − 1, JavaScript's largest exact
integer, the frontend's and any JSON client's): SQLite binds integers as signed 64-bit and
raises ``OverflowError`` from 2^63 on, which the routes would answer 500. A page's size is at
most ``MAX_PAGE`` (the store's). Imports only the store's page size.
"""

from __future__ import annotations

from typing import Annotated, Final

from fastapi import Path, Query

from cobot_hmi.service.storage.store import MAX_PAGE

MAX_INTEGER: Final = 2**53 - 1
"""The largest offset or id (``Number.MAX_SAFE_INTEGER``; SQLite's own is 2^63 − 1)."""

_OFFSET_HELP: Final = "skip this many rows (newest first), 0 to 2^53 − 1"

Offset = Annotated[int, Query(ge=0, le=MAX_INTEGER, description=_OFFSET_HELP)]
"""A page's offset (0 unless given)."""
OptionalOffset = Annotated[int | None, Query(ge=0, le=MAX_INTEGER, description=_OFFSET_HELP)]
"""A page's offset where its absence means something (the alarm history's CSV: the whole)."""
PageSize = Annotated[int, Query(ge=1, le=MAX_PAGE, description="at most this many rows")]
"""A page's size."""


def row_id(description: str) -> object:
    """A path parameter naming a row by its id (1 to ``MAX_INTEGER``), as ``Annotated``'s
    metadata: ``Annotated[int, row_id("the checkout's id")]``."""
    return Path(ge=1, le=MAX_INTEGER, description=description)


__all__ = ["MAX_INTEGER", "MAX_PAGE", "Offset", "OptionalOffset", "PageSize", "row_id"]

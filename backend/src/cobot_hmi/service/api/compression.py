"""Layer: service. gzip for the API's answers: Starlette's ``GZipMiddleware`` on the API's
paths, with the request's ``Accept-Encoding`` read by its weights (RFC 9110 §12.5.3).

Answers of ``GZIP_MINIMUM_BYTES`` or more are compressed when the request accepts gzip
(``GET …/tags`` is ~22 kB of JSON, ~2 kB gzipped); streamed answers (the CSV exports) chunk by
chunk, each flushed, so nothing waits for the end; chunks of 128 KiB and more are compressed on
a worker thread, not on the web loop. Left alone: the built frontend (precompressed, served
with its own ``Content-Encoding`` and ``Vary`` by ``static_files``), Parquet and MCAP exports
(zstd inside already), WebSockets (not an HTTP answer), and a request that refuses gzip with
``gzip;q=0`` (Starlette's middleware alone would see the word "gzip" and compress).

Imports Starlette and ``static_files`` only.
"""

from __future__ import annotations

from typing import Final

from starlette.datastructures import Headers
from starlette.middleware.gzip import (
    DEFAULT_EXCLUDED_CONTENT_TYPES,
    GZipMiddleware,
    GZipResponder,
    IdentityResponder,
)
from starlette.types import ASGIApp, Receive, Scope, Send

from cobot_hmi.service.api.static_files import choose_encoding

GZIP_MINIMUM_BYTES: Final = 1000
"""Answers shorter than this go as they are (compressing them saves less than its headers)."""
GZIP_LEVEL: Final = 6
"""zlib's default: most of level 9's saving at a fraction of its time."""
GZIP_EXCLUDED: Final = (
    *DEFAULT_EXCLUDED_CONTENT_TYPES,
    "application/vnd.apache.parquet",  # zstd inside already
    "application/octet-stream",  # MCAP exports: zstd chunks
)


class ApiGZipMiddleware(GZipMiddleware):
    """``GZipMiddleware`` for requests whose path starts with one of ``prefixes`` (without the
    leading slash), honouring a gzip weight of 0."""

    def __init__(self, app: ASGIApp, *, prefixes: tuple[str, ...]) -> None:
        super().__init__(
            app,
            minimum_size=GZIP_MINIMUM_BYTES,
            compresslevel=GZIP_LEVEL,
            exclude_content_types=GZIP_EXCLUDED,
        )
        self.prefixes = prefixes

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        path = scope.get("path", "") if scope["type"] == "http" else ""
        if not path.lstrip("/").startswith(self.prefixes):
            await self.app(scope, receive, send)
            return
        accepted = Headers(scope=scope).get("accept-encoding")
        responder: ASGIApp
        if choose_encoding(accepted, ("gzip",)) == "gzip":
            responder = GZipResponder(
                self.app,
                self.minimum_size,
                compresslevel=self.compresslevel,
                thread_minimum_size=self.thread_minimum_size,
                exclude_content_types=self.exclude_content_types,
            )
        else:  # as Starlette answers without gzip: the same Vary header
            responder = IdentityResponder(
                self.app, self.minimum_size, exclude_content_types=self.exclude_content_types
            )
        await responder(scope, receive, send)

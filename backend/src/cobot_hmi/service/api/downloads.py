"""Layer: service. A file the browser saves: a CSV export or report, a recorded history. One
place for what every download's answer carries: its media type, the name it is saved under
(``Content-Disposition: attachment``, RFC 6266) and, for a filtered part of a longer list,
the whole list's count (``X-Total-Count``)."""

from __future__ import annotations

from collections.abc import AsyncIterable, Iterable
from typing import Final

from fastapi import Response
from fastapi.responses import StreamingResponse

CSV_MEDIA_TYPE: Final = "text/csv; charset=utf-8"


def download(
    body: str | bytes | Iterable[str | bytes] | AsyncIterable[str | bytes],
    filename: str,
    *,
    media_type: str = CSV_MEDIA_TYPE,
    total: int | None = None,
) -> Response:
    """``body`` saved as ``filename``: all at once, or streamed as it is made (an iterable: the
    memory an export takes does not grow with what it exports; a plain one is iterated on
    Starlette's thread pool, off the event loop)."""
    headers = {"Content-Disposition": f'attachment; filename="{filename}"'}
    if total is not None:
        headers["X-Total-Count"] = str(total)
    if isinstance(body, str | bytes):
        return Response(body, media_type=media_type, headers=headers)
    return StreamingResponse(body, media_type=media_type, headers=headers)

"""Layer: service. The built frontend (``frontend/dist``) over HTTP, precompressed and cached.

A file under the root by its path, anything else that is not API its ``index.html`` (the
single-page app routes ``/kiosk`` and friends itself). ``npm run build`` writes ``NAME.br`` and
``NAME.gz`` next to every text asset (``frontend/scripts/precompress.mjs``); the answer is the
copy the request's ``Accept-Encoding`` allows (brotli before gzip, RFC 9110 §12.5.3 with its
``q`` weights), with ``Content-Encoding`` and ``Vary: Accept-Encoding``, so nothing is
compressed per request. Vite names the files under ``assets/`` by a hash of their content: they
never change under one name and are cached for a year as ``immutable``; ``index.html`` (which
names the current hashes) and everything else must be revalidated (``no-cache``).

Imports FastAPI and Starlette only; must not import the service's state.
"""

from __future__ import annotations

import mimetypes
from pathlib import Path
from typing import Final

from fastapi import FastAPI, Request
from fastapi.responses import FileResponse, JSONResponse, Response
from starlette.exceptions import HTTPException as StarletteHTTPException

HASHED_DIR: Final = "assets/"
"""Vite's ``build.assetsDir``: every file in it carries a content hash in its name."""

IMMUTABLE: Final = "public, max-age=31536000, immutable"
REVALIDATE: Final = "no-cache"

ENCODINGS: Final = (("br", ".br"), ("gzip", ".gz"))
"""Precompressed variants in order of preference (brotli is the smaller) and their suffixes."""


def accepted_encodings(header: str | None) -> dict[str, float]:
    """``Accept-Encoding``'s codings and their weights (RFC 9110 §12.5.3); bad parts ignored."""
    weights: dict[str, float] = {}
    if not header:
        return weights
    for part in header.split(","):
        name, _, params = part.strip().partition(";")
        name = name.strip().lower()
        if not name:
            continue
        q = 1.0
        for param in params.split(";"):
            key, _, value = param.strip().partition("=")
            if key.strip().lower() == "q":
                try:
                    q = float(value.strip())
                except ValueError:
                    q = 0.0  # an unreadable weight: do not assume the coding is wanted
        weights[name] = q
    return weights


def choose_encoding(header: str | None, available: tuple[str, ...]) -> str | None:
    """The coding to answer with among ``available`` (preference order), or None: identity."""
    weights = accepted_encodings(header)
    best: str | None = None
    best_q = 0.0
    for coding in available:
        q = weights.get(coding, weights.get("*", 0.0))
        if q > best_q:  # strict: a tie keeps the earlier, preferred coding
            best, best_q = coding, q
    return best


def _media_type(path: Path) -> str:
    """The original file's type (a ``.br`` copy must not be sent as a brotli archive)."""
    guessed, _ = mimetypes.guess_type(path.name)
    return guessed or "application/octet-stream"


def file_response(request: Request, path: Path, cache_control: str) -> Response:
    """``path`` (or its precompressed copy the request accepts) with its caching headers."""
    variants = {
        coding: path.with_name(path.name + suffix)
        for coding, suffix in ENCODINGS
        if path.with_name(path.name + suffix).is_file()
    }
    headers = {"Cache-Control": cache_control}
    if variants:
        headers["Vary"] = "Accept-Encoding"
    coding = choose_encoding(request.headers.get("accept-encoding"), tuple(variants))
    media_type = _media_type(path)
    if coding is None:
        return FileResponse(path, media_type=media_type, headers=headers)
    headers["Content-Encoding"] = coding
    return FileResponse(variants[coding], media_type=media_type, headers=headers)


def serve_frontend(app: FastAPI, root: Path, api_prefixes: tuple[str, ...]) -> None:
    """Answer every GET that no API route took from the built frontend under ``root``."""
    root = root.resolve()

    @app.get("/{path:path}", include_in_schema=False)
    async def frontend(path: str, request: Request) -> Response:
        if path.startswith(api_prefixes):
            raise StarletteHTTPException(404)
        index = root / "index.html"
        if not index.is_file():
            return JSONResponse(
                {"detail": {"reason": f"no built frontend at {root} (npm run build)"}}, 404
            )
        candidate = (root / path).resolve()
        if path and candidate.is_relative_to(root) and candidate.is_file():
            hashed = candidate.is_relative_to(root / HASHED_DIR)
            return file_response(request, candidate, IMMUTABLE if hashed else REVALIDATE)
        if Path(path).suffix and not path.endswith(".html"):
            raise StarletteHTTPException(404)  # a missing asset, not a page
        return file_response(request, index, REVALIDATE)

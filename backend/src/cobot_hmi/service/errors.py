"""Layer: service. The refusals the service answers with, as ``docs/api.md`` words them.

``detail`` is always an object with ``reason`` (plus ``field`` for 422, ``robot_reports``
for 504). Imports nothing of the project.
"""

from __future__ import annotations


class ApiError(Exception):
    """A refusal: HTTP ``status`` and ``detail`` (``reason`` and any extra keys)."""

    def __init__(self, status: int, reason: str, **extra: object) -> None:
        super().__init__(reason)
        self.status = status
        self.reason = reason
        self.detail: dict[str, object] = {"reason": reason, **extra}
        self.headers: dict[str, str] = {}


def unauthorized(reason: str = "login required") -> ApiError:
    error = ApiError(401, reason)
    error.headers["WWW-Authenticate"] = "Bearer"
    return error


def forbidden(reason: str) -> ApiError:
    return ApiError(403, reason)


def conflict(reason: str) -> ApiError:
    return ApiError(409, reason)

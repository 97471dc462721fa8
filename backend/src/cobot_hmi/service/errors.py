"""Layer: service. The refusals the service answers with, as ``docs/api.md`` words them.

``detail`` is always an object with ``reason`` and ``field`` (``None`` unless one part of the
request is at fault), plus ``robot_reports`` for 504 and ``known`` for an unknown robot
(``service.api.models.ApiErrorBody``). Imports nothing of the project.
"""

from __future__ import annotations


class ApiError(Exception):
    """A refusal: HTTP ``status`` and ``detail`` (``reason`` and any extra keys)."""

    def __init__(self, status: int, reason: str, **extra: object) -> None:
        super().__init__(reason)
        self.status = status
        self.reason = reason
        self.detail: dict[str, object] = {"reason": reason, "field": None, **extra}
        self.headers: dict[str, str] = {}


class AuditUnavailableError(ApiError):
    """The audit trail cannot be written (a full disk, a failed one): 503 with the reason.
    Whatever had to be audited before it acts was not done (``service.storage.store``)."""

    def __init__(self, reason: str) -> None:
        super().__init__(503, reason)

    def refusing(self, consequence: str) -> AuditUnavailableError:
        """The same refusal saying what was not done (``…: disk full; nothing was applied``)."""
        return AuditUnavailableError(f"{self.reason}; {consequence}")


def unauthorized(reason: str = "login required") -> ApiError:
    error = ApiError(401, reason)
    error.headers["WWW-Authenticate"] = "Bearer"
    return error


def forbidden(reason: str) -> ApiError:
    return ApiError(403, reason)


def conflict(reason: str) -> ApiError:
    return ApiError(409, reason)


def not_found(reason: str, **extra: object) -> ApiError:
    return ApiError(404, reason, **extra)


class UnknownRobotError(LookupError):
    """A robot name the settings do not list; the API answers 404 naming the known ones."""

    def __init__(self, name: str, known: list[str]) -> None:
        self.name = name
        self.known = list(known)
        super().__init__(f"unknown robot {name!r}; known: {', '.join(self.known) or 'none'}")

    def to_api_error(self, field: str = "name") -> ApiError:
        return not_found(str(self), field=field, known=self.known)

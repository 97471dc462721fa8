"""Layer: service. The API's contract: The error envelope every refusal answers with."""

from __future__ import annotations

from pydantic import BaseModel, Field

from cobot_hmi.service.api.models.frames import ElementValue

# --------------------------------------------------------------------------- errors


class ApiErrorBody(BaseModel):
    """Why a request was refused."""

    reason: str = Field(description="the refusal in words")
    field: str | None = Field(
        default=None,
        description="the part of the request at fault (``analog_output.0``, ``name``, a query "
        "parameter), when one is",
    )
    robot_reports: dict[str, ElementValue] | None = Field(
        default=None, description="504 only: what the robot's latest frame shows per element"
    )
    known: list[str] | None = Field(default=None, description="404 of a robot: the known names")


class ApiErrorResponse(BaseModel):
    """Every error answer: ``{"detail": {"reason": …, "field": …}}``."""

    detail: ApiErrorBody

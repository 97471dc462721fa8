"""Layer: service. Writing: ``PATCH …/command`` and control take / release, per robot, all through
the one write pipeline (``service.writes.pipeline``). The single-robot paths of the first release
answer for the first robot and are marked deprecated."""

from __future__ import annotations

from typing import Any, Final

from fastapi import APIRouter, Request

from cobot_hmi.service.api import models
from cobot_hmi.service.api.deps import DefaultRobotDep, RobotDep, WriterDep
from cobot_hmi.service.api.openapi_extras import CONTROL, WRITE, errors
from cobot_hmi.service.api.origin import request_origin
from cobot_hmi.service.api.routes.read import OrjsonResponse
from cobot_hmi.service.robots.robot import RobotRuntime
from cobot_hmi.service.writes.pipeline import (
    Writer,
    release_control,
    submit_write,
    take_control,
)

router = APIRouter(prefix="/api/v1", tags=["write"])

# The body is read by hand (FastAPI's own validation would answer 422 in another shape before
# the write is audited); ``models.CommandPatch`` (built from the layout) documents it.
_PATCH_BODY: Final[dict[str, Any]] = {
    "requestBody": {
        "required": True,
        "content": {
            "application/json": {
                "schema": {"$ref": "#/components/schemas/CommandPatch"},
                "example": models.COMMAND_PATCH_EXAMPLE,
            }
        },
    }
}
_DEPRECATED = "Deprecated: acts on the first robot; use /api/v1/robots/{name}/"


async def _write(robot: RobotRuntime, writer: Writer, request: Request) -> OrjsonResponse:
    outcome = await submit_write(
        robot, writer, await request.body(), origin=request_origin(request)
    )
    if not outcome.ok:
        raise outcome.error()
    return OrjsonResponse(outcome.answer())


_PATCH: Final[dict[str, Any]] = {
    "summary": "Write part of the O→T image; answers once the robot confirms it",
    "response_model": models.WriteConfirmed,
    "responses": errors(*WRITE),
    "openapi_extra": _PATCH_BODY,
}
_TAKE: Final[dict[str, Any]] = {
    "summary": "Take control: O→T to run, bumpless",
    "response_model": models.ControlStatus,
}
_RELEASE: Final[dict[str, Any]] = {
    "summary": "Release control: O→T back to idle (an admin may release anyone's)",
    "response_model": models.ControlStatus,
}


@router.patch("/robots/{name}/command", **_PATCH)
async def patch_command(robot: RobotDep, writer: WriterDep, request: Request) -> OrjsonResponse:
    return await _write(robot, writer, request)


@router.post("/robots/{name}/control/take", **_TAKE, responses=errors(*CONTROL))
async def take(robot: RobotDep, writer: WriterDep, request: Request) -> OrjsonResponse:
    return OrjsonResponse(await take_control(robot, writer, origin=request_origin(request)))


@router.post("/robots/{name}/control/release", **_RELEASE, responses=errors(*CONTROL))
async def release(robot: RobotDep, writer: WriterDep, request: Request) -> OrjsonResponse:
    return OrjsonResponse(await release_control(robot, writer, origin=request_origin(request)))


_DEFAULT_WRITE = tuple(s for s in WRITE if s != 404)
_DEFAULT_CONTROL = tuple(s for s in CONTROL if s != 404)


@router.patch(
    "/command",
    **{**_PATCH, "responses": errors(*_DEFAULT_WRITE)},
    deprecated=True,
    description=_DEPRECATED + "command",
)
async def patch_command_default(
    robot: DefaultRobotDep, writer: WriterDep, request: Request
) -> OrjsonResponse:
    return await _write(robot, writer, request)


@router.post(
    "/control/take",
    **_TAKE,
    responses=errors(*_DEFAULT_CONTROL),
    deprecated=True,
    description=_DEPRECATED + "control/take",
)
async def take_default(
    robot: DefaultRobotDep, writer: WriterDep, request: Request
) -> OrjsonResponse:
    return OrjsonResponse(await take_control(robot, writer, origin=request_origin(request)))


@router.post(
    "/control/release",
    **_RELEASE,
    responses=errors(*_DEFAULT_CONTROL),
    deprecated=True,
    description=_DEPRECATED + "control/release",
)
async def release_default(
    robot: DefaultRobotDep, writer: WriterDep, request: Request
) -> OrjsonResponse:
    return OrjsonResponse(await release_control(robot, writer, origin=request_origin(request)))

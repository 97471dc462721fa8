"""Layer: service. Read-only routes: the robots, each robot's frame, status and command, the
layout, health, readiness and metrics.

Per robot under ``/api/v1/robots/{name}/…``; the single-robot paths of the first release
(``/api/v1/frame``, ``/status``, ``/command``) answer for the first robot and are marked
deprecated. Answers are serialized with the codec's orjson ``dumps`` (tuples as arrays, NaN as
null); the ``response_model`` documents their shape.
"""

from __future__ import annotations

import functools
import time
from importlib import resources
from typing import Any, Final

from fastapi import APIRouter, Query, Request, Response
from fastapi.responses import JSONResponse

from cobot_hmi.codec import command_to_json, dumps, frame_to_json
from cobot_hmi.scanner.originator import ConnectionState
from cobot_hmi.service.access.auth import Session
from cobot_hmi.service.api import models
from cobot_hmi.service.api.deps import DefaultRobotDep, RobotDep, ServiceDep, ViewerDep
from cobot_hmi.service.api.metrics import ServiceMetrics
from cobot_hmi.service.api.openapi_extras import PROMETHEUS_CONTENT_TYPE, READ, errors
from cobot_hmi.service.errors import UnknownRobotError
from cobot_hmi.service.robots.robot import RobotRuntime
from cobot_hmi.service.runtime import Service

router = APIRouter()


class OrjsonResponse(JSONResponse):
    """JSON through the codec's ``dumps``: tuples as arrays, NaN/inf as null."""

    def render(self, content: object) -> bytes:
        return dumps(content)


_DEPRECATED = "Deprecated: answers for the first robot; use /api/v1/robots/{name}/"


@functools.cache
def _layout_bytes() -> bytes:
    return resources.files("cobot_hmi.generated").joinpath("layout.json").read_bytes()


@router.get(
    "/api/v1/layout",
    tags=["read"],
    summary="The layout document",
    response_model=models.LayoutDocument,
    responses=errors(401),
)
async def get_layout(_: ViewerDep) -> Response:
    return Response(_layout_bytes(), media_type="application/json")


# --------------------------------------------------------------------------- robots


def robot_summary(
    service: Service, robot: RobotRuntime, session: Session | None = None
) -> dict[str, object]:
    """``models.RobotSummary`` of one robot (no await: plain reads of its parts), its holder as
    ``session`` sees it (``holder.session_is_yours``)."""
    identity = robot.identity.to_json() if robot.identity is not None else None
    latest = robot.frames.latest
    state = latest[2].robot_state if latest is not None else None
    frame = frame_to_json(latest[2]) if latest is not None else None
    age_s, stale = _frame_age(service, robot)
    return {
        "name": robot.name,
        "host": robot.settings.host,
        "mode": robot.mode,
        "rpi_ms": robot.settings.rpi_ms,
        "model": identity["product_name"] if identity is not None else None,
        "identity": identity,
        "connection": robot.link.state.value,
        "connection_reason": robot.link.reason,
        "holder": robot.control.status_for(session)["holder"],
        "robot_state": state,
        "robot_state_name": frame["robot_state_name"] if frame is not None else None,
        "default": robot is service.default_robot,
        "alarms": robot.alarms.summary(),
        "frame_age_s": age_s,
        "stale": stale,
        "gaps": robot.alarms.gaps_total,
        "gaps_per_min": robot.alarms.gaps_per_min,
        "packet_loss_high": robot.alarms.packet_loss_high,
    }


@router.get(
    "/api/v1/robots",
    tags=["robots"],
    summary="The robots of the cell: connection, control and state of each",
    response_model=models.RobotList,
    responses=errors(401),
)
async def list_robots(service: ServiceDep, session: ViewerDep) -> OrjsonResponse:
    return OrjsonResponse(
        {"robots": [robot_summary(service, robot, session) for robot in service.robots.values()]}
    )


@router.get(
    "/api/v1/robots/{name}",
    tags=["robots"],
    summary="One robot: connection, control and state",
    response_model=models.RobotSummary,
    responses=errors(*READ),
)
async def get_robot(service: ServiceDep, robot: RobotDep, session: ViewerDep) -> OrjsonResponse:
    return OrjsonResponse(robot_summary(service, robot, session))


# --------------------------------------------------------------------------- one robot


def _frame_age(service: Service, robot: RobotRuntime) -> tuple[float | None, bool]:
    """How old the robot's newest frame is (s, ``None``: none yet) and whether it is stale
    (not connected, or older than ``stale_after_ms``)."""
    latest = robot.frames.latest
    if latest is None:
        return None, True
    age_s = max(0.0, time.time() - latest[1])
    stale = (
        age_s * 1000 > service.settings.stream.stale_after_ms
        or robot.link.state is not ConnectionState.CONNECTED
    )
    return age_s, stale


def _frame(service: Service, robot: RobotRuntime) -> dict[str, object]:
    latest = robot.frames.latest
    if latest is None:
        return {
            "robot": robot.name,
            "frame": None,
            "received_at": None,
            "age_s": None,
            "stale": True,
        }
    received_at, frame = latest[1], latest[2]
    age_s, stale = _frame_age(service, robot)
    return {
        "robot": robot.name,
        "frame": frame_to_json(frame),
        "received_at": received_at,
        "age_s": age_s,
        "stale": stale,
    }


async def _status(robot: RobotRuntime, session: Session | None) -> Any:
    answer = models.RobotStatus.model_validate(await robot.status()).model_dump(mode="json")
    answer["control"] = robot.control.status_for(session)  # holder.session_is_yours
    return answer


def _command(robot: RobotRuntime) -> dict[str, object]:
    return {
        "robot": robot.name,
        "image": command_to_json(robot.link.command),
        "run": robot.link.run,
    }


_FRAME: Final[dict[str, Any]] = {
    "tags": ["robots"],
    "summary": "The robot's latest decoded frame and its age",
    "response_model": models.FrameAnswer,
}
_STATUS: Final[dict[str, Any]] = {
    "tags": ["robots"],
    "summary": "The robot's connection state, counters and control",
    "response_model": models.RobotStatus,
}
_COMMAND: Final[dict[str, Any]] = {
    "tags": ["robots"],
    "summary": "The O→T image being sent to the robot, run or idle",
    "response_model": models.CommandState,
}


@router.get("/api/v1/robots/{name}/frame", **_FRAME, responses=errors(*READ))
async def get_frame(service: ServiceDep, robot: RobotDep, _: ViewerDep) -> OrjsonResponse:
    return OrjsonResponse(_frame(service, robot))


@router.get("/api/v1/robots/{name}/status", **_STATUS, responses=errors(*READ))
async def get_status(robot: RobotDep, session: ViewerDep) -> OrjsonResponse:
    return OrjsonResponse(await _status(robot, session))


@router.get("/api/v1/robots/{name}/command", **_COMMAND, responses=errors(*READ))
async def get_command(robot: RobotDep, _: ViewerDep) -> OrjsonResponse:
    return OrjsonResponse(_command(robot))


@router.get(
    "/api/v1/frame",
    **_FRAME,
    deprecated=True,
    description=_DEPRECATED + "frame",
    responses=errors(401),
)
async def get_frame_default(
    service: ServiceDep, robot: DefaultRobotDep, _: ViewerDep
) -> OrjsonResponse:
    return OrjsonResponse(_frame(service, robot))


@router.get(
    "/api/v1/status",
    **_STATUS,
    deprecated=True,
    description=_DEPRECATED + "status",
    responses=errors(401),
)
async def get_status_default(robot: DefaultRobotDep, session: ViewerDep) -> OrjsonResponse:
    return OrjsonResponse(await _status(robot, session))


@router.get(
    "/api/v1/command",
    **_COMMAND,
    deprecated=True,
    description=_DEPRECATED + "command",
    responses=errors(401),
)
async def get_command_default(robot: DefaultRobotDep, _: ViewerDep) -> OrjsonResponse:
    return OrjsonResponse(_command(robot))


# --------------------------------------------------------------------------- health


@router.get(
    "/healthz",
    tags=["health"],
    summary="The process serves, every cyclic thread lives, no link has been down too long",
    response_model=models.Health,
    responses={503: {"model": models.Health, "description": "something is wrong: see problems"}},
)
async def healthz(service: ServiceDep) -> OrjsonResponse:
    problems = service.health_problems()
    return OrjsonResponse({"ok": not problems, "problems": problems}, 503 if problems else 200)


def _ready(robot: RobotRuntime) -> tuple[dict[str, object], int]:
    ready, reason = robot.connection.ready()
    return {"ready": ready, "reason": reason, "robot": robot.name}, 200 if ready else 503


_NOT_READY: Final[dict[int | str, dict[str, Any]]] = {
    503: {"model": models.Ready, "description": "not connected to the robot"}
}


@router.get(
    "/readyz",
    tags=["health"],
    summary="Connected to the robot (?robot=NAME; default: every robot)",
    response_model=models.Ready,
    responses={**_NOT_READY, **errors(404)},
)
async def readyz(
    service: ServiceDep,
    robot: str | None = Query(default=None, description="one robot's readiness"),
) -> OrjsonResponse:
    if robot is not None:
        try:
            answer, status = _ready(service.robot(robot))
        except UnknownRobotError as error:
            raise error.to_api_error("robot") from None
        return OrjsonResponse(answer, status)
    for one in service.robots.values():
        answer, status = _ready(one)
        if status != 200:
            return OrjsonResponse(answer, status)
    return OrjsonResponse({"ready": True, "reason": None, "robot": None})


@router.get(
    "/api/v1/robots/{name}/readyz",
    tags=["health"],
    summary="Connected to this robot",
    response_model=models.Ready,
    responses={**_NOT_READY, **errors(404)},
)
async def robot_readyz(robot: RobotDep) -> OrjsonResponse:
    answer, status = _ready(robot)
    return OrjsonResponse(answer, status)


@router.get(
    "/metrics",
    tags=["health"],
    summary="Prometheus metrics, per robot with a robot label",
    response_class=Response,
    responses={
        200: {
            "description": "Prometheus text exposition format 0.0.4",
            "content": {PROMETHEUS_CONTENT_TYPE: {"schema": {"type": "string"}}},
        }
    },
)
async def metrics(request: Request) -> Response:
    registry: ServiceMetrics = request.app.state.metrics
    return Response(await registry.exposition(), media_type=PROMETHEUS_CONTENT_TYPE)

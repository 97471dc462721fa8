"""Layer: service. A robot's health (``service.health``, docs/health.md): the verdicts and
figures now, their trend, the weekly report as CSV, read by anyone who may view; the baselines,
listed by the same, created by an operator or above (audited, with a reason)."""

from __future__ import annotations

import time
from typing import Annotated, Final

from fastapi import APIRouter, Query, Request, Response

from cobot_hmi.codec import dumps
from cobot_hmi.service.api.deps import RobotDep, ServiceDep, ViewerDep, WriterDep
from cobot_hmi.service.api.downloads import download
from cobot_hmi.service.api.models_health import (
    HealthBaseline,
    HealthBaselineCreate,
    HealthBaselineList,
    HealthReport,
    HealthTrend,
)
from cobot_hmi.service.api.openapi_extras import CSV_RESPONSE, errors
from cobot_hmi.service.api.origin import audited_action
from cobot_hmi.service.api.search import From, To, epoch_s
from cobot_hmi.service.errors import ApiError
from cobot_hmi.service.health.answers import report_csv, trend_answer

router = APIRouter(prefix="/api/v1", tags=["health"])

WEEK_S: Final = 7 * 86_400.0
MAX_POINTS: Final = 10_000
_JSON: Final = "application/json"


def _json(body: object, status_code: int = 200) -> Response:
    return Response(dumps(body), media_type=_JSON, status_code=status_code)


@router.get(
    "/robots/{name}/health",
    summary="The robot's health now: each joint's verdict (ok, watch, act), its reason in a "
    "sentence and its figures (friction, reducer life, heat, knocks), the cycle time against "
    "the baseline's, the knocks of this shift with where in joint space, the baseline in use",
    response_model=HealthReport,
    responses=errors(401, 404, 409),
)
async def get_health(service: ServiceDep, robot: RobotDep, _: ViewerDep) -> Response:
    return _json(await service.health.answer(robot.name))


@router.get(
    "/robots/{name}/health/trend",
    summary="The robot's health over days: the figures of each snapshot (every "
    "health_snapshot_s) in the range, oldest first (default: the last 7 days)",
    response_model=HealthTrend,
    responses=errors(401, 404, 409, 422),
)
async def get_health_trend(
    service: ServiceDep,
    robot: RobotDep,
    _: ViewerDep,
    since: From = None,
    until: To = None,
    limit: Annotated[
        int, Query(ge=1, le=MAX_POINTS, description="at most this many (the newest) points")
    ] = MAX_POINTS,
) -> Response:
    from_s, to_s = _range(since, until)
    snapshots = await service.health.trend(robot.name, from_s, to_s, limit)
    return _json(trend_answer(robot.name, snapshots))


@router.get(
    "/robots/{name}/health/report.csv",
    summary="The weekly health report as CSV: per day of the plant's time zone, each joint's "
    "verdict and figures at the day's last snapshot (default: the last 7 days)",
    response_class=Response,
    responses={
        200: {
            "description": "a header row (robot, period_from, period_to, day, time, "
            "baseline_id, joint, the figures), then one row per joint per day; times in "
            "ISO 8601",
            "content": CSV_RESPONSE,
        },
        **errors(401, 404, 409, 422),
    },
)
async def get_health_report(
    service: ServiceDep, robot: RobotDep, _: ViewerDep, since: From = None, until: To = None
) -> Response:
    from_s, to_s = _range(since, until)
    snapshots = await service.health.trend(robot.name, from_s, to_s, MAX_POINTS)
    return download(
        report_csv(robot.name, snapshots, from_s, to_s), f"{robot.name}-health-report.csv"
    )


@router.get(
    "/robots/{name}/health/baselines",
    summary="The robot's baselines, oldest first: who set each, why, when, from which cycles, "
    "which is active and which is being learned",
    response_model=HealthBaselineList,
    responses=errors(401, 404, 409),
)
async def list_baselines(service: ServiceDep, robot: RobotDep, _: ViewerDep) -> Response:
    return _json({"items": await service.health.baselines(robot.name)})


@router.post(
    "/robots/{name}/health/baselines",
    summary="Learn a new baseline from the next N whole cycles (after a reducer change, a new "
    "program): the verdicts restart from it once learned; the one in use stays until then. "
    "Operator or above; audited with its reason",
    response_model=HealthBaseline,
    status_code=201,
    responses=errors(401, 403, 404, 409, 422, 503),
)
async def create_baseline(
    service: ServiceDep,
    robot: RobotDep,
    writer: WriterDep,
    request: Request,
    body: HealthBaselineCreate,
) -> Response:
    action = audited_action(robot, writer, request, "health.baseline")
    requested = {"reason": body.reason, "cycles": body.cycles}
    user = await action.authorize("setting a health baseline", requested)
    try:
        baseline = await service.health.begin_baseline(
            robot.name, body.reason.strip(), user, body.cycles
        )
    except ApiError as error:  # health off, no cycles to learn from: the refusal audited
        raise await action.refused(error, requested=requested) from None
    await action.audit(
        "started",
        requested={**requested, "baseline": baseline["id"]},
        reason=body.reason.strip(),
        summary=f"health baseline {baseline['id']} from the next {body.cycles} cycles: "
        f"{body.reason.strip()}",
    )
    return _json(baseline, status_code=201)


def _range(since: str | None, until: str | None) -> tuple[float, float]:
    to_s = epoch_s(until)
    to_s = time.time() if to_s is None else to_s
    from_s = epoch_s(since)
    return (to_s - WEEK_S if from_s is None else from_s), to_s

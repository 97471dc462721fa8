"""Layer: service. A robot's health (``service.health``, docs/health.md): the verdicts and
figures now, their trend, the weekly report as CSV, read by anyone who may view; the baselines,
listed by the same, created by an operator or above (audited, with a reason)."""

from __future__ import annotations

import asyncio
import time
from datetime import UTC, datetime
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
from cobot_hmi.service.health.period import PeriodCycle, PeriodRequest
from cobot_hmi.service.runtime import Service

router = APIRouter(prefix="/api/v1", tags=["health"])

WEEK_S: Final = 7 * 86_400.0
MAX_POINTS: Final = 10_000
_JSON: Final = "application/json"
DEFAULT_CYCLES: Final = 50
"""A baseline's cycles when neither cycles nor a period is given."""
MAX_PERIOD_CYCLES: Final = 100_000
"""The most cycles of a period read (a week of 6 s cycles)."""
RECENT_S: Final = 10.0
FLUSH_TIMEOUT_S: Final = 5.0


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
    summary="Learn a new baseline (after a reducer change, a new program): from the next N "
    "whole cycles (the verdicts restart from it once learned; the one in use stays until then), "
    "or from a period already recorded (from, to: its recorded frames and measured cycles, "
    "adopted at once). Operator or above; audited with its reason",
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
    reason = body.reason.strip()
    period = body.period_s() if body.from_ is not None else None
    requested: dict[str, object] = {"reason": body.reason}
    if period is None:
        requested["cycles"] = cycles = body.cycles or DEFAULT_CYCLES
    else:
        requested["from"], requested["to"] = period
    user = await action.authorize("setting a health baseline", requested)
    try:
        if period is None:
            baseline = await service.health.begin_baseline(robot.name, reason, user, cycles)
            summary = f"from the next {cycles} cycles"
        else:
            request_ = PeriodRequest(reason, user, time.time(), *period)
            baseline = await _learn_period(service, robot.name, request_)
            summary = f"from the period {_iso(period[0])} to {_iso(period[1])}"
    except ApiError as error:  # health off, no cycles or recording to learn from: audited
        raise await action.refused(error, requested=requested) from None
    await action.audit(
        "started" if period is None else "saved",  # learned and adopted at once
        requested={**requested, "baseline": baseline["id"]},
        reason=reason,
        summary=f"health baseline {baseline['id']} {summary}: {reason}",
    )
    return _json(baseline, status_code=201)


async def _learn_period(service: Service, name: str, request: PeriodRequest) -> dict[str, object]:
    """A baseline of the robot's recording of the period and the cycles the cycle meter stored
    in it (``service.health.period``); ``ApiError`` 409 without either."""
    from_s, to_s = request.from_s, request.to_s
    recorder = service.recorder
    if recorder is None:
        raise ApiError(409, "history is off: a period's baseline is learned from its recording")
    if to_s > time.time() - RECENT_S:  # the period reaches the present: its last frames written
        await asyncio.to_thread(recorder.flush, FLUSH_TIMEOUT_S)
    store = service.cycles.store
    await store.flush()
    stored = await store.read_range(
        name, since=from_s, until=to_s, limit=MAX_PERIOD_CYCLES, last_n=1, include_interrupted=True
    )
    cycles = [
        PeriodCycle(float(c["start"]), float(c["end"]), bool(c["interrupted"]))  # type: ignore[arg-type]
        for c in stored.cycles
        if float(c["end"]) <= to_s  # type: ignore[arg-type]
    ]
    return await service.health.learn_period(name, request, service.settings.history_path, cycles)


def _iso(epoch: float) -> str:
    return datetime.fromtimestamp(epoch, UTC).isoformat(timespec="seconds")


def _range(since: str | None, until: str | None) -> tuple[float, float]:
    to_s = epoch_s(until)
    to_s = time.time() if to_s is None else to_s
    from_s = epoch_s(since)
    return (to_s - WEEK_S if from_s is None else from_s), to_s

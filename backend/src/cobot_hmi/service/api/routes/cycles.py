"""Layer: service. A robot's measured cycles and their statistics (``service.cycles``), JSON
or CSV; read by anyone who may view."""

from __future__ import annotations

from typing import Annotated, Final, Literal

from fastapi import APIRouter, Query, Response

from cobot_hmi.codec import dumps
from cobot_hmi.service.api.deps import RobotDep, ServiceDep, ViewerDep
from cobot_hmi.service.api.downloads import download
from cobot_hmi.service.api.models_cycles import CyclePage
from cobot_hmi.service.api.openapi_extras import CSV_RESPONSE, errors
from cobot_hmi.service.api.search import From, To, epoch_s
from cobot_hmi.service.cycles.store import CYCLE_COLUMNS
from cobot_hmi.service.storage.store import MAX_PAGE, to_csv

router = APIRouter(prefix="/api/v1", tags=["cycles"])

DEFAULT_LIMIT: Final = 1000
DEFAULT_LAST: Final = 20


@router.get(
    "/robots/{name}/cycles",
    summary="The robot's cycles in a range and their statistics (last, mean/min/max of the "
    "last N, count); interrupted cycles are marked and left out of the statistics unless "
    "include_interrupted",
    responses={
        200: {
            "model": CyclePage,
            "description": "the cycles, oldest first (format=csv: one row per cycle, ISO 8601 "
            "times, the count in the range in X-Total-Count)",
            "content": CSV_RESPONSE,
        },
        **errors(401, 404, 422),
    },
)
async def get_cycles(
    service: ServiceDep,
    robot: RobotDep,
    _: ViewerDep,
    since: From = None,
    until: To = None,
    *,
    limit: Annotated[
        int, Query(ge=1, le=MAX_PAGE, description="at most this many (the newest) cycles")
    ] = DEFAULT_LIMIT,
    last: Annotated[
        int, Query(ge=1, le=MAX_PAGE, description="N: mean, min and max are of the newest N")
    ] = DEFAULT_LAST,
    format: Annotated[Literal["json", "csv"], Query(description="csv: the cycles as CSV")] = "json",
    include_interrupted: Annotated[
        bool,
        Query(
            description="true: the statistics include the interrupted cycles (a stop, a lost "
            "link, the robot out of its running states); by default they leave them out"
        ),
    ] = False,
) -> Response:
    cycles = service.cycles
    await cycles.store.flush()  # what was measured before the request is in the answer
    found = await cycles.store.read_range(
        robot.name,
        since=epoch_s(since),
        until=epoch_s(until),
        limit=limit,
        last_n=last,
        include_interrupted=include_interrupted,
    )
    if format == "csv":
        return download(
            to_csv(found.cycles, CYCLE_COLUMNS, time_columns=("start", "end")),
            f"cycles-{robot.name}.csv",
            total=found.stats.count + (0 if include_interrupted else found.stats.interrupted),
        )
    meter = cycles.meters.get(robot.name)
    stats = found.stats
    page = {
        "robot": robot.name,
        "trigger": None
        if meter is None
        else {"text": meter.trigger.text, "label": meter.trigger.label},
        "cycles": found.cycles,
        "statistics": {
            "count": stats.count,
            "interrupted": stats.interrupted,
            "include_interrupted": include_interrupted,
            "last_s": stats.last_s,
            "window": stats.window,
            "mean_s": stats.mean_s,
            "min_s": stats.min_s,
            "max_s": stats.max_s,
        },
        "in_progress_since": None if meter is None else meter.started_at,
    }
    return Response(dumps(page), media_type="application/json")

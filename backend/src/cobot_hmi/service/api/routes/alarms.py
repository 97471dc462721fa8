"""Layer: service. Alarms: the current ones of every robot (or one, ``?robot=``), the cell's at a
glance (``/alarms/summary``), one alarm, its acknowledgement (one, or many in one request: one
audited action each) and shelving (operator role, audited as writes are), and the history (JSON
or CSV with ISO 8601 times).

An alarm's id is ``robot:key`` (``left:emergency_stop``, ``left:motor_temperature.2`` is J 3's):
the robot part picks the robot's engine (``RobotRuntime.alarms``). Every change is also an
``alarm`` event on that robot's stream and in the event log.
"""

from __future__ import annotations

from collections.abc import AsyncIterator, Callable
from dataclasses import dataclass
from typing import Annotated, Any, Final, Literal, TypeVar

from fastapi import APIRouter, Body, Path, Query, Request, Response

from cobot_hmi.codec import dumps
from cobot_hmi.service.alarms.engine import (
    AlarmEngine,
    AlarmRefusedError,
    NotShelvableError,
    UnknownAlarmError,
)
from cobot_hmi.service.alarms.persistence import HISTORY_CSV_COLUMNS, AlarmStore
from cobot_hmi.service.alarms.summary import annunciated
from cobot_hmi.service.api import models
from cobot_hmi.service.api.bounds import OptionalOffset
from cobot_hmi.service.api.deps import RobotFilterDep, ServiceDep, ViewerDep, WriterDep
from cobot_hmi.service.api.downloads import download
from cobot_hmi.service.api.openapi_extras import CSV_RESPONSE, errors
from cobot_hmi.service.api.origin import request_origin
from cobot_hmi.service.api.routes.read import OrjsonResponse
from cobot_hmi.service.api.search import From, Text, To, epoch_s
from cobot_hmi.service.errors import ApiError, conflict, not_found
from cobot_hmi.service.robots.robot import RobotRuntime
from cobot_hmi.service.runtime import Service
from cobot_hmi.service.storage.store import MAX_PAGE, AuditEntry, to_csv
from cobot_hmi.service.writes.pipeline import Writer, authorize_audited

HISTORY_FILENAME: Final = "alarm-history.csv"

router = APIRouter(prefix="/api/v1", tags=["alarms"])

AlarmId = Annotated[
    str,
    Path(
        description="``robot:key``, e.g. ``left:emergency_stop`` (URL-encode the colon as %3A "
        "if your client insists)",
        json_schema_extra={"pattern": r"^[a-z0-9][a-z0-9_-]{0,31}:[a-z0-9_.-]+$"},
    ),
]
_CHANGE: Final = (401, 403, 404, 409, 413, 415, 422, 429)
_T = TypeVar("_T")


def _engine(service: Service, alarm_id: str) -> tuple[RobotRuntime, AlarmEngine]:
    name, colon, key = alarm_id.partition(":")
    robot = service.robots.get(name) if colon and key else None
    if robot is None:
        known = ", ".join(service.robots)
        raise not_found(
            f"no alarm {alarm_id!r}: an alarm id is robot:key, robots: {known}", field="alarm_id"
        )
    return robot, robot.alarms


def _find(engine: AlarmEngine, alarm_id: str) -> None:
    try:
        engine.find(alarm_id)
    except UnknownAlarmError:
        raise not_found(
            f"robot {engine.robot} has no alarm {alarm_id!r}", field="alarm_id"
        ) from None


@router.get(
    "/alarms",
    summary="Alarms that are active or unacknowledged (every robot, or ?robot=), most urgent first",
    response_model=models.AlarmList,
    responses=errors(401, 404, 422),
)
async def list_alarms(
    service: ServiceDep,
    _: ViewerDep,
    robot: RobotFilterDep,
    *,
    which: Annotated[
        Literal["current", "all"],
        Query(description="current: active or unacknowledged; all: every alarm, normal too"),
    ] = "current",
) -> OrjsonResponse:
    robots = [service.robot(robot)] if robot is not None else list(service.robots.values())
    items: list[dict[str, object]] = []
    for one in robots:
        items.extend(one.alarms.current() if which == "current" else one.alarms.all())
    items.sort(key=_urgency)
    return OrjsonResponse({"items": items, "total": len(items)})


@router.get(
    "/alarms/summary",
    summary="Every robot's alarms at a glance: counts by priority and the most urgent one",
    response_model=models.CellAlarmSummary,
    responses=errors(401),
)
async def alarm_summary(service: ServiceDep, _: ViewerDep) -> OrjsonResponse:
    return OrjsonResponse(service.cell_alarms())


def _urgency(alarm: dict[str, object]) -> tuple[int, float]:
    """Most urgent first: priority, then the newest change."""
    rank, changed = alarm["priority_rank"], alarm["changed_at"]
    return (
        rank if isinstance(rank, int) else 3,
        -changed if isinstance(changed, int | float) else 0.0,
    )


DEFAULT_PAGE: Final = 100


@router.get(
    "/alarms/history",
    summary="Every alarm transition, newest first (JSON, or CSV with ISO 8601 times)",
    responses={
        200: {
            "model": models.AlarmHistoryPage,
            "description": "a page, newest first (format=csv: the whole filtered history as "
            "CSV, streamed, unless limit or offset asks for a page; the total in X-Total-Count)",
            "content": CSV_RESPONSE,
        },
        **errors(401, 404, 422),
    },
)
async def alarm_history(
    service: ServiceDep,
    _: ViewerDep,
    robot: RobotFilterDep,
    *,
    priority: Annotated[
        models.AlarmPriority | None, Query(description="only this priority")
    ] = None,
    since: Annotated[
        float | None, Query(description="from this time on, s since the epoch")
    ] = None,
    until: Annotated[float | None, Query(description="before this time, s since the epoch")] = None,
    from_: From = None,
    to: To = None,
    q: Text = None,
    limit: Annotated[
        int | None, Query(ge=1, le=MAX_PAGE, description="page size (JSON: 100 unless given)")
    ] = None,
    offset: OptionalOffset = None,
    format: Annotated[
        Literal["json", "csv"],
        Query(description="csv: the whole filtered history (or the page asked for) as CSV"),
    ] = "json",
) -> Response:
    store = service.default_robot.alarm_store
    since = since if since is not None else epoch_s(from_)  # from/to: the words of every search
    until = until if until is not None else epoch_s(to)
    if format == "csv" and limit is None and offset is None:
        return await _history_csv(
            store, robot=robot, priority=priority, since=since, until=until, q=q
        )
    page = await store.history_page(
        limit or DEFAULT_PAGE,
        offset or 0,
        robot=robot,
        priority=priority,
        since=since,
        until=until,
        q=q,
    )
    if format == "csv":
        return download(to_csv(page.items, HISTORY_CSV_COLUMNS), HISTORY_FILENAME, total=page.total)
    return Response(
        dumps({"items": page.items, "total": page.total}), media_type="application/json"
    )


async def _history_csv(
    store: AlarmStore,
    *,
    robot: str | None,
    priority: str | None,
    since: float | None,
    until: float | None,
    q: str | None,
) -> Response:
    """The whole filtered history as CSV, newest first, streamed a batch of rows at a time
    (memory does not grow with the history), as of the request: later transitions are not in
    it, so the rows match X-Total-Count."""
    total, newest_id = await store.history_count(
        robot=robot, priority=priority, since=since, until=until, q=q
    )

    async def body() -> AsyncIterator[str]:
        yield to_csv([], HISTORY_CSV_COLUMNS)
        async for items in store.history_all(
            newest_id, robot=robot, priority=priority, since=since, until=until, q=q
        ):
            yield to_csv(items, HISTORY_CSV_COLUMNS, header=False)

    return download(body(), HISTORY_FILENAME, total=total)


@router.get(
    "/alarms/{alarm_id}",
    summary="One alarm and its state",
    response_model=models.Alarm,
    responses=errors(401, 404),
)
async def get_alarm(service: ServiceDep, _: ViewerDep, alarm_id: AlarmId) -> OrjsonResponse:
    engine = _engine(service, alarm_id)[1]
    _find(engine, alarm_id)
    return OrjsonResponse(engine.snapshot(engine.find(alarm_id)))


@dataclass(frozen=True, slots=True)
class _Change:
    """An operator's change of one alarm, authorized: what the audit row of its outcome needs."""

    robot: RobotRuntime
    engine: AlarmEngine
    writer: Writer
    user: str
    action: str
    key: str
    requested: dict[str, Any]
    origin: str

    async def audit(self, outcome: str, reason: str | None, summary: str | None = None) -> None:
        """The outcome's audit row. It is about what already happened (an alarm's state is
        changed in memory, its history row queued): on a full disk it waits in memory and is
        written once there is room (``keep_audit``), and the answer says what happened."""
        await self.robot.store.keep_audit(
            AuditEntry(
                self.user,
                self.writer.client,
                self.action,
                [self.key],
                None,
                self.requested,
                outcome,
                reason,
                robot=self.robot.name,
                origin=self.origin,
                summary=summary,
            ),
            happened=outcome != "refused",
        )

    async def act(
        self, change: Callable[[], _T], refused: Callable[[AlarmRefusedError], ApiError]
    ) -> _T:
        """``change()`` on the engine; a refusal audited and raised as ``refused(error)``.
        The alarm's new state is in the database before the answer (on a full disk it waits in
        memory and is written, in order, once there is room: ``AlarmStore.flush``)."""
        try:
            result = change()
        except AlarmRefusedError as error:
            await self.audit("refused", str(error))
            raise refused(error) from None
        await self.robot.alarm_store.flush()
        return result


async def _authorize(
    service: Service,
    writer: Writer,
    request: Request,
    alarm_id: str,
    *,
    action: str,
    what: str,
    requested: dict[str, Any] | None,
) -> _Change:
    """The alarm (404), then the writer's role (401 / 403, audited as a write's refusal is).

    ``requested`` is what the audit rows show was asked; ``None`` shows as null on a refusal
    of the role and as ``{}`` on the outcome's row."""
    robot, engine = _engine(service, alarm_id)
    _find(engine, alarm_id)
    key = alarm_id.partition(":")[2]
    origin = request_origin(request)
    user = await authorize_audited(
        robot.store,
        writer,
        action=action,
        what=what,
        robot=robot.name,
        origin=origin,
        fields=[key],
        requested=requested,
    )
    asked = {} if requested is None else requested
    return _Change(robot, engine, writer, user, action, key, asked, origin)


def _summary(alarm: dict[str, object], what: str) -> str:
    where = alarm.get("label")
    tag = alarm.get("tag")
    if where and tag:
        where = f"{where} ({tag})"
    return f"{alarm['name']}{f' [{where}]' if where else ''}: {what}"


def _shelve_refused(error: AlarmRefusedError) -> ApiError:
    """409 for an alarm that is never shelved (a safety stop, a critical alarm), 422 naming
    the longest shelving for a duration over it."""
    if isinstance(error, NotShelvableError):
        return ApiError(409, str(error), field="alarm_id")
    return ApiError(422, str(error), field="duration_s")


def _conflict(error: AlarmRefusedError) -> ApiError:
    return conflict(str(error))


async def _authorize_ack(
    service: Service, writer: Writer, request: Request, alarm_id: str, comment: str | None
) -> _Change:
    return await _authorize(
        service,
        writer,
        request,
        alarm_id,
        action="alarm.ack",
        what="acknowledging alarms",
        requested={"comment": comment},
    )


async def _acknowledge(change: _Change, alarm_id: str, comment: str | None) -> dict[str, Any]:
    """Acknowledge one authorized alarm and audit the outcome; 409 ``ApiError`` (audited as
    refused) for a normal alarm. ``{alarm, changed, reason}`` (``reason``: why unchanged)."""
    alarm, changed = await change.act(
        lambda: change.engine.acknowledge(alarm_id, change.user, comment), _conflict
    )
    unchanged = (
        f"suppressed by design (a consequence of {alarm['suppressed_by_name']}): nothing to "
        "acknowledge"
        if alarm["state"] == "suppressed"
        else "already acknowledged"
    )
    await change.audit(
        "acknowledged" if changed else "unchanged",
        None if changed else unchanged,
        _summary(alarm, "acknowledged" + (f" — {comment}" if comment else "")),
    )
    return {"alarm": alarm, "changed": changed, "reason": None if changed else unchanged}


def _comment(text: str | None) -> str | None:
    return text.strip() or None if text else None


@router.post(
    "/alarms/{alarm_id}/ack",
    summary="Acknowledge an alarm (operator): active → active-acknowledged, returned → normal",
    response_model=models.AlarmAnswer,
    responses=errors(*_CHANGE),
)
async def acknowledge(
    service: ServiceDep,
    writer: WriterDep,
    request: Request,
    alarm_id: AlarmId,
    body: Annotated[models.AlarmAck | None, Body()] = None,
) -> OrjsonResponse:
    comment = _comment(body.comment if body is not None else None)
    change = await _authorize_ack(service, writer, request, alarm_id, comment)
    answer = await _acknowledge(change, alarm_id, comment)
    return OrjsonResponse({"alarm": answer["alarm"], "changed": answer["changed"]})


def _alarms_asked(service: Service, body: models.AlarmAckMany) -> list[str]:
    """The ids ``body`` asks for, each known (404 otherwise), or every alarm of its robot that
    is unacknowledged and annunciated."""
    if (body.ids is None) == (body.robot is None):
        raise ApiError(
            422, "give either ids (the alarms) or robot (all of its alarms)", field="ids"
        )
    if body.ids is not None:
        alarm_ids = list(dict.fromkeys(body.ids))
        for alarm_id in alarm_ids:
            _find(_engine(service, alarm_id)[1], alarm_id)
        return alarm_ids
    engine = service.robot(body.robot or "").alarms
    return [
        engine.alarm_id(key)
        for key, alarm in engine.alarms.items()
        if annunciated(alarm.status) and not alarm.status.state.acknowledged
    ]


async def _ack_result(change: _Change, alarm_id: str, comment: str | None) -> dict[str, object]:
    """One ``AlarmAckResult``: acknowledged, unchanged, or refused (a normal alarm)."""
    try:
        answer = await _acknowledge(change, alarm_id, comment)
    except ApiError as error:  # nothing to acknowledge: audited as refused
        alarm = change.engine.snapshot(change.engine.find(alarm_id))
        return {"id": alarm_id, "outcome": "refused", "reason": error.reason, "alarm": alarm}
    return {
        "id": alarm_id,
        "outcome": "acknowledged" if answer["changed"] else "unchanged",
        "reason": answer["reason"],
        "alarm": answer["alarm"],
    }


@router.post(
    "/alarms/ack",
    summary="Acknowledge several alarms (operator): the ids given, or every unacknowledged, "
    "annunciated alarm of one robot; one audited action per alarm",
    response_model=models.AlarmAckManyAnswer,
    responses=errors(401, 403, 404, 413, 415, 422, 429),
)
async def acknowledge_many(
    service: ServiceDep, writer: WriterDep, request: Request, body: models.AlarmAckMany
) -> OrjsonResponse:
    """Every alarm named must exist (else 404, nothing acknowledged, nothing audited); a
    writer below the operator role is refused with one audit row per alarm (401/403); then
    each alarm is acknowledged and audited in turn, as ``POST /alarms/{id}/ack`` does it."""
    alarm_ids = _alarms_asked(service, body)
    comment = _comment(body.comment)
    changes: list[_Change] = []
    refusal: ApiError | None = None
    for alarm_id in alarm_ids:  # a refusal of the role is audited for every alarm asked
        try:
            changes.append(await _authorize_ack(service, writer, request, alarm_id, comment))
        except ApiError as error:
            refusal = error
    if not alarm_ids:  # nothing to acknowledge, but only an operator is told so
        robot = service.robot(body.robot) if body.robot else service.default_robot
        await authorize_audited(
            robot.store,
            writer,
            action="alarm.ack",
            what="acknowledging alarms",
            robot=robot.name,
            origin=request_origin(request),
            requested={"comment": comment},
        )
    if refusal is not None:
        raise refusal
    items = [
        await _ack_result(change, alarm_id, comment)
        for alarm_id, change in zip(alarm_ids, changes, strict=True)
    ]
    acknowledged = sum(item["outcome"] == "acknowledged" for item in items)
    return OrjsonResponse({"items": items, "acknowledged": acknowledged})


@router.post(
    "/alarms/{alarm_id}/shelve",
    summary="Shelve an alarm (operator): not annunciated until it expires, is unshelved, or "
    "its condition clears and comes again; never a safety stop or a critical alarm (409), at "
    "most its priority's longest (422)",
    response_model=models.AlarmAnswer,
    responses=errors(*_CHANGE),
)
async def shelve(
    service: ServiceDep,
    writer: WriterDep,
    request: Request,
    alarm_id: AlarmId,
    body: models.AlarmShelve,
) -> OrjsonResponse:
    change = await _authorize(
        service,
        writer,
        request,
        alarm_id,
        action="alarm.shelve",
        what="shelving alarms",
        requested={"reason": body.reason, "duration_s": body.duration_s},
    )
    alarm = await change.act(
        lambda: change.engine.shelve(alarm_id, change.user, body.reason, body.duration_s),
        _shelve_refused,
    )
    summary = _summary(alarm, f"shelved for {body.duration_s:g} s — {body.reason.strip()}")
    await change.audit("shelved", None, summary)
    return OrjsonResponse({"alarm": alarm, "changed": True})


@router.post(
    "/alarms/{alarm_id}/unshelve",
    summary="Unshelve an alarm (operator)",
    response_model=models.AlarmAnswer,
    responses=errors(*_CHANGE),
)
async def unshelve(
    service: ServiceDep, writer: WriterDep, request: Request, alarm_id: AlarmId
) -> OrjsonResponse:
    change = await _authorize(
        service,
        writer,
        request,
        alarm_id,
        action="alarm.unshelve",
        what="unshelving alarms",
        requested=None,
    )
    alarm, changed = await change.act(
        lambda: change.engine.unshelve(alarm_id, change.user), _conflict
    )
    await change.audit(
        "unshelved" if changed else "unchanged",
        None if changed else "not shelved",
        _summary(alarm, "unshelved"),
    )
    return OrjsonResponse({"alarm": alarm, "changed": changed})

"""Layer: service. I/O checkouts (loop checks) per robot (``service.commissioning``): start one,
read its points, let the frames mark inputs seen, switch outputs through the write pipeline,
record pass or fail, close it (read-only after), and its report as CSV. Reading is open to
whoever may view; every change needs an operator and is audited (``checkout.*`` actions; a
switched output is the pipeline's own ``write`` row).

The commissioning state is the service's (``Service.commissioning``, started with it): the open
checkouts are read back and watched again.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Mapping
from typing import Annotated, Final

from fastapi import APIRouter, Path, Request, Response

from cobot_hmi.service.api.bounds import row_id
from cobot_hmi.service.api.deps import RobotDep, ViewerDep, WriterDep
from cobot_hmi.service.api.downloads import download
from cobot_hmi.service.api.openapi_extras import WRITE, errors
from cobot_hmi.service.api.origin import audited_action
from cobot_hmi.service.api.routes.read import OrjsonResponse
from cobot_hmi.service.commissioning import models
from cobot_hmi.service.commissioning.checkout import Checkout, CheckoutBook, CheckoutError
from cobot_hmi.service.commissioning.service import Commissioning
from cobot_hmi.service.robots.robot import RobotRuntime
from cobot_hmi.service.runtime import Service
from cobot_hmi.service.storage.store import iso8601
from cobot_hmi.service.writes.pipeline import submit_write

router = APIRouter(prefix="/api/v1", tags=["checkouts"])

_READ: Final = errors(401, 404)
_CHANGE: Final = errors(401, 403, 404, 409, 413, 415, 422, 429, 503)
CheckoutId = Annotated[int, row_id("the checkout's id (POST …/checkouts)")]
PointKey = Annotated[
    str, Path(description="the point's key, field.index: controlbox_di.4 is DI 5", max_length=40)
]
CSV_COLUMNS: Final = (
    "checkout",
    "robot",
    "started_at",
    "closed_at",
    "key",
    "label",
    "tag",
    "kind",
    "result",
    "seen_at",
    "seen_before",
    "seen_after",
    "samples",
    "switched_at",
    "switched_value",
    "switched_by",
    "switches",
    "recorded_at",
    "recorded_by",
    "comment",
)


def _commissioning(request: Request) -> Commissioning:
    service: Service = request.app.state.service
    return service.commissioning


def _book(request: Request, robot: RobotRuntime) -> CheckoutBook:
    return _commissioning(request).checkouts[robot.name]


def _watch(request: Request, robot: RobotRuntime) -> None:
    """Watch the robot's frames while it has an open checkout (after a start or a close)."""
    _commissioning(request).watchers[robot.name].update()


@router.get(
    "/robots/{name}/checkouts",
    summary="The robot's checkouts, newest first (without their points)",
    response_model=models.CheckoutList,
    responses=_READ,
)
async def list_checkouts(robot: RobotDep, _: ViewerDep, request: Request) -> OrjsonResponse:
    return OrjsonResponse({"items": await _book(request, robot).summaries()})


@router.post(
    "/robots/{name}/checkouts",
    summary="Start a checkout: every I/O point and bit register of the layout, untested (409 "
    "while the robot has an open checkout: resume that one)",
    response_model=models.Checkout,
    status_code=201,
    responses=_CHANGE,
)
async def start_checkout(robot: RobotDep, writer: WriterDep, request: Request) -> OrjsonResponse:
    action = audited_action(robot, writer, request, "checkout.start")
    user = await action.authorize("starting a checkout")
    identity = robot.identity.to_json() if robot.identity is not None else None
    try:
        checkout = await _book(request, robot).start(user, identity)
    except CheckoutError as error:
        raise await action.refused(error) from None
    _watch(request, robot)
    await action.audit(
        "started",
        requested={"checkout": checkout.id},
        summary=f"checkout {checkout.id} started",
    )
    return OrjsonResponse(checkout.answer(robot.tags.names), status_code=201)


@router.get(
    "/robots/{name}/checkouts/{checkout_id}",
    summary="A checkout with every point: label, result, times and who",
    response_model=models.Checkout,
    responses=_READ,
)
async def get_checkout(
    robot: RobotDep, checkout_id: CheckoutId, _: ViewerDep, request: Request
) -> OrjsonResponse:
    checkout = await _book(request, robot).get(checkout_id)
    return OrjsonResponse(checkout.answer(robot.tags.names))


@router.post(
    "/robots/{name}/checkouts/{checkout_id}/points/{key}/result",
    summary="Record pass or fail of a point with a comment (pass: seen, or confirmed by the robot; "
    "fail: a comment is needed)",
    response_model=models.CheckoutPoint,
    responses=_CHANGE,
)
async def record_result(
    robot: RobotDep,
    *,
    checkout_id: CheckoutId,
    key: PointKey,
    verdict: models.CheckoutVerdict,
    writer: WriterDep,
    request: Request,
) -> OrjsonResponse:
    action = audited_action(robot, writer, request, "checkout.result")
    requested = {"checkout": checkout_id, **verdict.model_dump()}
    user = await action.authorize("recording a result", requested)
    book = _book(request, robot)
    checkout = await book.get(checkout_id)
    try:
        state = await book.record(checkout, key, verdict.result, verdict.comment, user)
    except CheckoutError as error:
        raise await action.refused(error, [key], requested) from None
    comment = f" ({verdict.comment})" if verdict.comment else ""
    await action.audit(
        "recorded",
        fields=[key],
        requested=requested,
        summary=f"checkout {checkout.id}: {state.point.label} {verdict.result}{comment}",
    )
    return OrjsonResponse(state.answer(robot.tags.names.get(key)))


@router.post(
    "/robots/{name}/checkouts/{checkout_id}/points/{key}/switch",
    summary="Switch an output from the checkout: one write through the write pipeline (control "
    "needed), answered once the robot confirmed it",
    response_model=models.CheckoutPoint,
    responses=errors(*WRITE),
)
async def switch_output(
    robot: RobotDep,
    *,
    checkout_id: CheckoutId,
    key: PointKey,
    switch: models.CheckoutSwitch,
    writer: WriterDep,
    request: Request,
) -> OrjsonResponse:
    action = audited_action(robot, writer, request, "write")  # the pipeline's own action
    book = _book(request, robot)
    checkout = await book.get(checkout_id)
    try:
        state = checkout.open_point(key)
        if state.point.kind != "output":
            raise CheckoutError(409, f"{state.point.label} is an input: the robot reports it")
    except CheckoutError as error:
        raise await action.refused(error, [key], {"value": switch.value}) from None
    point = state.point
    body = {point.field: {str(point.index): switch.value}}
    outcome = await submit_write(robot, writer, body, origin=action.origin)
    if not outcome.ok:
        raise outcome.error()
    assert writer.user is not None  # the pipeline authorized the writer
    await book.switched(
        checkout,
        key,
        switch.value,
        latency_ms=outcome.latency_ms,
        seq=outcome.seq,
        by=writer.user,
    )
    return OrjsonResponse(state.answer(robot.tags.names.get(key)))


@router.post(
    "/robots/{name}/checkouts/{checkout_id}/points/{key}/capture",
    summary="Capture an analog input's value now (two captures at values the checker chooses "
    "make it seen)",
    response_model=models.CheckoutPoint,
    responses=_CHANGE,
)
async def capture_input(
    robot: RobotDep,
    checkout_id: CheckoutId,
    key: PointKey,
    writer: WriterDep,
    request: Request,
) -> OrjsonResponse:
    action = audited_action(robot, writer, request, "checkout.capture")
    requested: dict[str, object] = {"checkout": checkout_id}
    user = await action.authorize("capturing a value", requested)
    book = _book(request, robot)
    checkout = await book.get(checkout_id)
    latest = robot.frames.latest
    try:
        state = checkout.open_point(key)
        if latest is None:
            raise CheckoutError(409, "no frame from the robot yet: nothing to capture")
        if state.point.signal != "analog" or state.point.kind != "input":
            raise CheckoutError(409, f"{state.point.label} is not an analog input")
        value = float(getattr(latest.frame, state.point.field)[state.point.index])
        await book.capture(checkout, key, value, latest.received_at_s, user)
    except CheckoutError as error:
        raise await action.refused(error, [key], requested) from None
    await action.audit(
        "captured",
        fields=[key],
        requested={**requested, "value": value},
        summary=f"checkout {checkout.id}: {state.point.label} = {value:g}",
    )
    return OrjsonResponse(state.answer(robot.tags.names.get(key)))


@router.post(
    "/robots/{name}/checkouts/{checkout_id}/close",
    summary="Close a checkout: read-only from now on",
    response_model=models.Checkout,
    responses=_CHANGE,
)
async def close_checkout(
    robot: RobotDep, checkout_id: CheckoutId, writer: WriterDep, request: Request
) -> OrjsonResponse:
    action = audited_action(robot, writer, request, "checkout.close")
    requested: dict[str, object] = {"checkout": checkout_id}
    user = await action.authorize("closing a checkout", requested)
    book = _book(request, robot)
    checkout = await book.get(checkout_id)
    try:
        await book.close(checkout, user)
    except CheckoutError as error:
        raise await action.refused(error, [], requested) from None
    _watch(request, robot)
    counts = checkout.counts()
    await action.audit(
        "closed",
        requested={**requested, "counts": counts},
        summary=f"checkout {checkout.id} closed: "
        + ", ".join(f"{n} {result}" for result, n in counts.items()),
    )
    return OrjsonResponse(checkout.answer(robot.tags.names))


@router.get(
    "/robots/{name}/checkouts/{checkout_id}/report.csv",
    summary="The checkout's report as CSV: every point with its result, who and when, every "
    "switch of an output with its confirmation time",
    response_class=Response,
    responses={
        200: {
            "description": "CSV with a header row, one row per point, times in ISO 8601",
            "content": {"text/csv": {"schema": {"type": "string"}}},
        },
        **_READ,
    },
)
async def report_csv(
    robot: RobotDep, checkout_id: CheckoutId, _: ViewerDep, request: Request
) -> Response:
    checkout = await _book(request, robot).get(checkout_id)
    return download(report(checkout, robot.tags.names), f"{robot.name}-checkout-{checkout.id}.csv")


def _time(value: object) -> str:
    return iso8601(value) if isinstance(value, float | int) else ""


def _cell(value: object) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "on" if value else "off"
    return str(value)


def _switch_words(switch: dict[str, object]) -> str:
    """One switch in the report: "on confirmed 2026-12-07T05:01:02.345678+01:00 by olivia"."""
    return (
        f"{_cell(switch.get('value'))} confirmed {_time(switch.get('time'))} by {switch.get('by')}"
    )


def report(checkout: Checkout, tags: Mapping[str, str]) -> str:
    """The CSV report: one row per point, in layout order."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    for state in checkout.points.values():
        p = state.answer(tags.get(state.point.key))
        samples = " ".join(f"{s['value']:g}@{_time(s['time'])}" for s in state.samples)
        switches = "; ".join(_switch_words(s) for s in state.switches)
        writer.writerow(
            (
                checkout.id,
                checkout.robot,
                _time(checkout.started_at),
                _time(checkout.closed_at),
                p["key"],
                p["label"],
                _cell(p["tag"]),
                p["kind"],
                p["result"],
                _time(p["seen_at"]),
                _cell(p["seen_before"]),
                _cell(p["seen_after"]),
                samples,
                _time(p["switched_at"]),
                _cell(p["switched_value"]),
                _cell(p["switched_by"]),
                switches,
                _time(p["recorded_at"]),
                _cell(p["recorded_by"]),
                _cell(p["comment"]),
            )
        )
    return out.getvalue()

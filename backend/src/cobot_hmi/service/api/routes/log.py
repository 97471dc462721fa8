"""Layer: service. The event log (read by anyone who may view: ``view_requires_login``) and the
audit trail (operator and above: it names users and client addresses), JSON or CSV, all robots or
one (``?robot=NAME``), searched by time range and text (``?from=&to=&q=``, ``api.search``)."""

from __future__ import annotations

from typing import Annotated, Any, Final, Literal

from fastapi import APIRouter, Query, Response

from cobot_hmi.codec import dumps
from cobot_hmi.service.api import models
from cobot_hmi.service.api.bounds import Offset, PageSize
from cobot_hmi.service.api.deps import OperatorDep, RobotFilterDep, ServiceDep, ViewerDep
from cobot_hmi.service.api.downloads import download
from cobot_hmi.service.api.openapi_extras import CSV_RESPONSE, LOG, errors
from cobot_hmi.service.api.search import From, Text, To, epoch_s
from cobot_hmi.service.events.text import with_text
from cobot_hmi.service.labels import labels_of
from cobot_hmi.service.storage.search import Search
from cobot_hmi.service.storage.store import (
    AUDIT_COLUMNS,
    EVENT_COLUMNS,
    Page,
    event_csv_rows,
    to_csv,
)

router = APIRouter(prefix="/api/v1", tags=["log"])

Format = Annotated[Literal["json", "csv"], Query(description="csv: the whole page as CSV")]
Kind = Annotated[models.EventKind | None, Query(description="only events of this kind")]


def _responses(model: type) -> dict[int | str, dict[str, Any]]:
    return {
        200: {
            "model": model,
            "description": "a page, newest first (format=csv: as CSV, the total in X-Total-Count)",
            "content": CSV_RESPONSE,
        },
        **errors(*LOG),
    }


def _answer(page: Page, columns: tuple[str, ...], fmt: str, name: str) -> Response:
    if fmt == "csv":
        rows = event_csv_rows(page.items) if name == "events" else page.items
        return download(to_csv(rows, columns), f"{name}.csv", total=page.total)
    return Response(
        dumps({"items": page.items, "total": page.total}), media_type="application/json"
    )


_AUDIT: Final = "Write attempts and control changes, newest first"
_EVENTS: Final = "Connection, robot state, flag, write and control events, newest first"


@router.get("/audit", summary=_AUDIT, responses=_responses(models.AuditPage))
async def get_audit(
    service: ServiceDep,
    _: OperatorDep,
    robot: RobotFilterDep,
    since: From = None,
    until: To = None,
    *,
    q: Text = None,
    limit: PageSize = 100,
    offset: Offset = 0,
    format: Format = "json",
) -> Response:
    search = Search(epoch_s(since), epoch_s(until), q)
    page = await service.store.audit_page(limit, offset, robot=robot, search=search)
    for item in page.items:  # the spec's label of each key: controlbox_do.2 is DO 3
        item["labels"] = labels_of(item.get("fields"))
    return _answer(page, (*AUDIT_COLUMNS, "labels"), format, "audit")


@router.get("/events", summary=_EVENTS, responses=_responses(models.EventPage))
async def get_events(
    service: ServiceDep,
    _: ViewerDep,
    robot: RobotFilterDep,
    since: From = None,
    until: To = None,
    *,
    q: Text = None,
    kind: Kind = None,
    limit: PageSize = 100,
    offset: Offset = 0,
    format: Format = "json",
) -> Response:
    search = Search(epoch_s(since), epoch_s(until), q)
    page = await service.store.events_page(kind, limit, offset, robot=robot, search=search)
    for item in page.items:  # in words (a row logged before events had its text gets it)
        with_text(item)
    return _answer(page, EVENT_COLUMNS, format, "events")

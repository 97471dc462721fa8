"""Layer: service. The audit trail and the event log (operator and above), JSON or CSV."""

from __future__ import annotations

from typing import Annotated, Literal

from fastapi import APIRouter, Query, Response

from cobot_hmi.codec import dumps
from cobot_hmi.service.deps import OperatorDep, ServiceDep
from cobot_hmi.service.store import AUDIT_COLUMNS, EVENT_COLUMNS, MAX_PAGE, Page, to_csv

router = APIRouter(prefix="/api/v1", tags=["log"])

Limit = Annotated[int, Query(ge=1, le=MAX_PAGE)]
Offset = Annotated[int, Query(ge=0)]
Format = Annotated[Literal["json", "csv"], Query()]


def _answer(page: Page, columns: tuple[str, ...], fmt: str, name: str) -> Response:
    if fmt == "csv":
        return Response(
            to_csv(page.items, columns),
            media_type="text/csv; charset=utf-8",
            headers={
                "Content-Disposition": f'attachment; filename="{name}.csv"',
                "X-Total-Count": str(page.total),
            },
        )
    return Response(
        dumps({"items": page.items, "total": page.total}), media_type="application/json"
    )


@router.get("/audit", summary="Write attempts and control changes, newest first")
async def get_audit(
    service: ServiceDep,
    _: OperatorDep,
    limit: Limit = 100,
    offset: Offset = 0,
    format: Format = "json",
) -> Response:
    page = await service.store.audit_page(limit, offset)
    return _answer(page, AUDIT_COLUMNS, format, "audit")


@router.get("/events", summary="Connection, robot state, flag, write and control events")
async def get_events(
    service: ServiceDep,
    _: OperatorDep,
    kind: str | None = None,
    limit: Limit = 100,
    offset: Offset = 0,
    format: Format = "json",
) -> Response:
    page = await service.store.events_page(kind, limit, offset)
    return _answer(page, EVENT_COLUMNS, format, "events")

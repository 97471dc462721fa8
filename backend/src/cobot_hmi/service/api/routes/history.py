"""Layer: service. A robot's recorded history: decimated ranges for plots and exports
(``docs/api.md``, History). The work (reading segments, decimating, encoding an export) runs on
worker threads, never on the event loop; an export streams chunk by chunk.
"""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections.abc import Iterator
from datetime import UTC, datetime
from pathlib import Path
from typing import Annotated, Any, Final

import orjson
from fastapi import APIRouter, Query, Response

from cobot_hmi.history import export as history_export
from cobot_hmi.history import segments
from cobot_hmi.history.query import MAX_POINTS, QueryError, QueryResult, check_range, query
from cobot_hmi.history.schema import Element, UnknownFieldError, select_elements
from cobot_hmi.history.times import TimeFormatError, parse_time
from cobot_hmi.service.api import models
from cobot_hmi.service.api.deps import RobotDep, ServiceDep, ViewerDep
from cobot_hmi.service.api.downloads import download
from cobot_hmi.service.api.openapi_extras import READ, errors
from cobot_hmi.service.errors import ApiError
from cobot_hmi.service.events.text import with_text
from cobot_hmi.service.plant_time import PLANT_ZONE
from cobot_hmi.service.recording.history_settings import HistorySettings
from cobot_hmi.service.recording.recorder import Recorder
from cobot_hmi.service.runtime import Service
from cobot_hmi.service.storage.history_events import events_between, iter_events

router = APIRouter(prefix="/api/v1/robots/{name}", tags=["history"])

_TIME_HELP: Final = (
    "ISO 8601 (2026-11-24T06:00:00Z; without an offset: UTC) or seconds since the epoch"
)
From = Annotated[str, Query(alias="from", description="start of the range: " + _TIME_HELP)]
To = Annotated[str, Query(description="end of the range (excluded): " + _TIME_HELP)]
Fields = Annotated[
    str | None,
    Query(
        description="comma-separated field names (joint_position) or elements "
        "(joint_position.2); default: every field"
    ),
]
Points = Annotated[int, Query(ge=1, le=MAX_POINTS, description="buckets, at most 5000")]
Format = Annotated[models.ExportFormat, Query(description="csv, parquet or mcap")]

_EXPORT: Final[dict[str, Any]] = {
    "content": {
        media: {"schema": {"type": "string", "format": "binary", "description": what}}
        for media, what in (
            ("text/csv", "one column per element, units in the header, ISO 8601 times"),
            ("application/vnd.apache.parquet", "the recording's columns (docs/api.md)"),
            (
                "application/octet-stream",
                "MCAP: /ROBOT/frames and /ROBOT/events, JSON + JSON Schema",
            ),
        )
    }
}


def _times(from_text: str, to_text: str, points: int) -> tuple[float, float]:
    try:
        from_s = parse_time(from_text)
    except TimeFormatError as error:
        raise ApiError(422, str(error), field="from") from None
    try:
        to_s = parse_time(to_text)
    except TimeFormatError as error:
        raise ApiError(422, str(error), field="to") from None
    try:
        check_range(from_s, to_s, points)
    except QueryError as error:
        raise ApiError(422, str(error), field=error.field) from None
    return from_s, to_s


def _elements(fields: str | None) -> list[Element]:
    try:
        return select_elements(fields.split(",") if fields else None)
    except UnknownFieldError as error:
        raise ApiError(422, str(error), field="fields") from None


def answer_json(result: QueryResult, paused_reason: str | None, recording: bool) -> bytes:
    """The ``HistoryAnswer`` of a query result (numpy arrays written as they are)."""
    series = []
    for s in result.series:
        e = s.element
        item: dict[str, object] = {
            "element": e.name,
            "field": e.field.name,
            "label": e.label,
            "unit": e.unit,
        }
        if s.values is not None:
            item["values"] = s.values
        item.update(s.stats)
        series.append(item)
    body: dict[str, object] = {
        "robot": result.robot,
        "from": result.from_s,
        "to": result.to_s,
        "points": result.points,
        "mode": result.mode,
        "bucket_s": result.bucket_s,
        "frames": result.frames,
        "t": result.t,
        "seq": result.seq,
        "t2o_sequence": result.t2o_sequence,
        "count": result.count,
        "t_first": result.t_first,
        "t_last": result.t_last,
        "series": series,
        "recording": recording and paused_reason is None,
        "recording_paused_reason": paused_reason,
    }
    return orjson.dumps(body, option=orjson.OPT_SERIALIZE_NUMPY)


def _recording(service: Service) -> tuple[bool, str | None]:
    recorder = service.recorder
    if recorder is None:
        return False, None
    return True, recorder.paused_reason


@router.get(
    "/history",
    summary="A range of the robot's recorded frames, decimated for a plot (min/max/first/last "
    "per bucket, or the raw frames)",
    response_model=models.HistoryAnswer,
    responses=errors(*READ, 422),
)
async def get_history(
    service: ServiceDep,
    robot: RobotDep,
    _: ViewerDep,
    *,
    from_: From,
    to: To,
    fields: Fields = None,
    points: Points = 1000,
) -> Response:
    from_s, to_s = _times(from_, to, points)
    elements = _elements(fields)
    recording, paused_reason = _recording(service)

    def work() -> bytes:
        result = query(
            service.settings.history_path,
            robot.name,
            elements,
            from_s=from_s,
            to_s=to_s,
            points=points,
        )
        return answer_json(result, paused_reason, recording)

    return Response(await asyncio.to_thread(work), media_type="application/json")


EventLimit = Annotated[int, Query(ge=1, le=10_000, description="at most this many events")]
EventKind = Annotated[
    list[models.EventKind] | None, Query(description="only events of these kinds (repeatable)")
]


@router.get(
    "/history/events",
    summary="The robot's events of a range (markers for history plots), oldest first",
    response_model=models.HistoryEvents,
    responses=errors(*READ, 422),
)
async def get_history_events(
    service: ServiceDep,
    robot: RobotDep,
    _: ViewerDep,
    *,
    from_: From,
    to: To,
    kind: EventKind = None,
    limit: EventLimit = 1000,
) -> Response:
    from_s, to_s = _times(from_, to, 1)
    await service.store.flush_events()  # the events queued so far are in the answer
    kinds: set[str] | None = {str(k) for k in kind} if kind else None

    def work() -> bytes:
        events = events_between(
            service.settings.web.database_path,
            robot.name,
            from_s,
            to_s,
            limit=limit + 1,
            kinds=kinds,
        )
        items = [with_text(event) for event in events[:limit]]
        return orjson.dumps({"items": items, "truncated": len(events) > limit})

    return Response(await asyncio.to_thread(work), media_type="application/json")


def history_status(
    root: Path, robot: str, recorder: Recorder | None, settings: HistorySettings
) -> dict[str, object]:
    """What is recorded of ``robot`` (``HistoryStatus``)."""
    closed = segments.list_segments(root, robot)
    journals = segments.list_journals(root, robot)
    starts = [s.start_us for s in closed] + [start for start, _ in journals]
    size = sum(s.size_bytes() for s in closed)
    for _, path in journals:
        with contextlib.suppress(OSError):
            size += path.stat().st_size
    track = recorder.tracks.get(robot) if recorder is not None else None
    last = track.last_time_s if track is not None else None
    if last is None and closed:
        last = closed[-1].end_us / 1e6
    return {
        "robot": robot,
        "recording": recorder is not None and recorder.paused_reason is None,
        "recording_paused_reason": recorder.paused_reason if recorder is not None else None,
        "first": min(starts) / 1e6 if starts else None,
        "last": last,
        "segments": len(closed),
        "bytes": size,
        "retention_days": settings.history_retention_days,
        "retention_bytes": settings.history_retention_bytes,
    }


@router.get(
    "/history/status",
    summary="What is recorded of the robot: the range kept, its size, recording or paused",
    response_model=models.HistoryStatus,
    responses=errors(*READ),
)
async def get_history_status(service: ServiceDep, robot: RobotDep, _: ViewerDep) -> Response:
    status = await asyncio.to_thread(
        history_status,
        service.settings.history_path,
        robot.name,
        service.recorder,
        service.settings.recording,
    )
    return Response(orjson.dumps(status), media_type="application/json")


EXPORT_FLUSH_TIMEOUT_S: Final = 2.0
"""How long an export reaching the present waits for the recorder's flush (``_recorded_until``)."""


async def _recorded_until(service: Service, to_s: float) -> None:
    """An export whose range reaches the frames the recorder may still hold (the last
    ``history_flush_s``) has them written first, so it holds everything the page showed up to
    the request; a recorder that does not answer in time leaves it as recorded so far."""
    recorder = service.recorder
    if recorder is None or to_s < time.time() - 2 * service.settings.recording.history_flush_s:
        return
    await asyncio.to_thread(recorder.flush, EXPORT_FLUSH_TIMEOUT_S)


def export_chunks(
    root: Path,
    database: Path,
    robot: str,
    elements: list[Element],
    *,
    from_s: float,
    to_s: float,
    fmt: str,
    zone: str = "UTC",
) -> Iterator[bytes]:
    """The export's bytes (also ``cobot-hmi export``): frames and, for MCAP, the events; the
    CSV's times in ``zone`` (the plant's, ``plant_time``)."""
    events = (
        (with_text(event) for event in iter_events(database, robot, from_s, to_s))
        if fmt == "mcap"
        else iter(())
    )
    tables = history_export.tables(root, robot, elements, from_s=from_s, to_s=to_s, fmt=fmt)
    lines = 0
    for chunk in history_export.export(tables, robot, elements, fmt, events, zone=zone):
        if chunk:
            lines += chunk.count(b"\n")
            yield chunk
    if fmt == "csv" and lines <= 1:  # the header alone: the file says why it holds no row
        yield nothing_recorded_line(from_s, to_s)


def nothing_recorded_line(from_s: float, to_s: float) -> bytes:
    """The last line of a CSV export of a range without a recorded frame: "# nothing recorded
    from 2026-12-07T04:00:00.000000Z to 2026-12-07T04:02:00.000000Z" (the plot says the same,
    frontend lib/plots/plotExport.ts); pandas skips it with ``comment="#"``."""

    def utc(time_s: float) -> str:
        return datetime.fromtimestamp(time_s, UTC).strftime("%Y-%m-%dT%H:%M:%S.%fZ")

    return f"# nothing recorded from {utc(from_s)} to {utc(to_s)}\n".encode()


@router.get(
    "/export",
    summary="A range of the robot's recorded frames as a file: CSV, Parquet or MCAP (streamed)",
    responses={
        200: {
            "description": "the file, named after the robot and the range",
            **_EXPORT,
        },
        **errors(*READ, 422),
    },
    response_class=Response,
)
async def get_export(
    service: ServiceDep,
    robot: RobotDep,
    _: ViewerDep,
    *,
    from_: From,
    to: To,
    format: Format,
    fields: Fields = None,
) -> Response:
    from_s, to_s = _times(from_, to, 1)
    elements = _elements(fields)
    await _recorded_until(service, to_s)
    filename = history_export.export_filename(robot.name, from_s, to_s, format)
    chunks = export_chunks(
        service.settings.history_path,
        service.settings.web.database_path,
        robot.name,
        elements,
        from_s=from_s,
        to_s=to_s,
        fmt=format,
        zone=PLANT_ZONE.name,
    )
    return download(chunks, filename, media_type=history_export.MEDIA_TYPES[format])

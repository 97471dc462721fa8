"""Layer: service. Tag names of a robot's I/O points and bit registers
(``service.storage.tags``): read by anyone who may view, changed by an admin only (audited),
exported and imported as CSV.

Keys are ``name.index`` with the frame array's 0-based index; every answer names the spec's
label beside it (``controlbox_do.2`` is DO 3). The import takes the CSV inside a JSON body
(``{"csv": "…"}``): the service accepts only JSON request bodies (docs/api.md "Cross-site
rules").
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Final

from fastapi import APIRouter, Request, Response

from cobot_hmi.service.access.users import Role
from cobot_hmi.service.api import models
from cobot_hmi.service.api.deps import RobotDep, ViewerDep, WriterDep
from cobot_hmi.service.api.downloads import download
from cobot_hmi.service.api.openapi_extras import errors
from cobot_hmi.service.api.origin import request_origin
from cobot_hmi.service.api.routes.read import OrjsonResponse
from cobot_hmi.service.errors import ApiError
from cobot_hmi.service.robots.robot import RobotRuntime
from cobot_hmi.service.storage.store import AuditEntry
from cobot_hmi.service.storage.tags import POINTS, POINTS_BY_KEY, TagError, from_csv, to_csv
from cobot_hmi.service.writes.pipeline import Writer, authorize_audited

router = APIRouter(prefix="/api/v1", tags=["tags"])

_CHANGE: Final = (401, 403, 404, 413, 415, 422, 429)


def _tag_list(robot: RobotRuntime) -> dict[str, object]:
    names = robot.tags.names
    return {
        "robot": robot.name,
        "points": [
            {
                "key": p.key,
                "label": p.label,
                "field": p.field,
                "index": p.index,
                "directions": list(p.directions),
                "name": names.get(p.key),
            }
            for p in POINTS
        ],
        "tags": dict(names),
    }


@router.get(
    "/robots/{name}/tags",
    summary="Every taggable point of the robot with its label and tag name",
    response_model=models.TagList,
    responses=errors(401, 404),
)
async def get_tags(robot: RobotDep, _: ViewerDep) -> OrjsonResponse:
    return OrjsonResponse(_tag_list(robot))


@router.get(
    "/robots/{name}/tags.csv",
    summary="The tag names as CSV: key,label,name (every point; unnamed ones empty)",
    response_class=Response,
    responses={
        200: {
            "description": "CSV with a header row",
            "content": {"text/csv": {"schema": {"type": "string"}}},
        },
        **errors(401, 404),
    },
)
async def get_tags_csv(robot: RobotDep, _: ViewerDep) -> Response:
    return download(to_csv(robot.tags.names), f"{robot.name}-tags.csv")


def _changes(before: Mapping[str, str], after: Mapping[str, str]) -> list[str]:
    keys = set(before) | set(after)
    order = {p.key: i for i, p in enumerate(POINTS)}
    return sorted((k for k in keys if before.get(k) != after.get(k)), key=lambda k: order.get(k, 0))


def _summary(before: Mapping[str, str], after: Mapping[str, str], keys: list[str]) -> str:
    parts = []
    for key in keys:
        label = POINTS_BY_KEY[key].label if key in POINTS_BY_KEY else key
        new = after.get(key)
        parts.append(f"{label} = {new!r}" if new else f"{label}: name removed")
    return "; ".join(parts) or "no change"


async def _replace(
    robot: RobotRuntime, writer: Writer, request: Request, tags: Mapping[str, object], how: str
) -> OrjsonResponse:
    origin = request_origin(request)
    user = await authorize_audited(
        robot.store,
        writer,
        action="tags.update",
        what="naming tags",
        robot=robot.name,
        origin=origin,
        role=Role.ADMIN,
        requested={"tags": dict(tags), "how": how},
    )
    before = dict(robot.tags.names)
    try:
        after = await robot.tags.replace(robot.store, tags)
    except TagError as error:
        await robot.store.add_audit(
            AuditEntry(
                user,
                writer.client,
                "tags.update",
                [],
                None,
                {"how": how},
                "invalid",
                error.reason,
                robot=robot.name,
                origin=origin,
            )
        )
        raise ApiError(422, error.reason, field=error.field) from None
    keys = _changes(before, after)
    await robot.store.add_audit(
        AuditEntry(
            user,
            writer.client,
            "tags.update",
            keys,
            None,
            {
                "how": how,
                "before": {k: before.get(k) for k in keys},
                "after": {k: after.get(k) for k in keys},
            },
            "updated" if keys else "unchanged",
            None,
            robot=robot.name,
            origin=origin,
            summary=_summary(before, after, keys),
            tags={k: v for k, v in after.items() if k in keys},
        )
    )
    return OrjsonResponse(_tag_list(robot))


@router.put(
    "/robots/{name}/tags",
    summary="Replace the robot's tag names (admin; audited)",
    response_model=models.TagList,
    responses=errors(*_CHANGE),
)
async def put_tags(
    robot: RobotDep, writer: WriterDep, request: Request, body: models.TagUpdate
) -> OrjsonResponse:
    return await _replace(robot, writer, request, body.tags, "json")


@router.post(
    "/robots/{name}/tags/import",
    summary="Replace the robot's tag names from CSV key,label,name (admin; audited)",
    response_model=models.TagList,
    responses=errors(*_CHANGE),
)
async def import_tags(
    robot: RobotDep, writer: WriterDep, request: Request, body: models.TagImport
) -> OrjsonResponse:
    try:
        tags = from_csv(body.csv)
    except TagError as error:
        # Authorization first: a viewer learns nothing from a refusal of the sheet.
        origin = request_origin(request)
        user = await authorize_audited(
            robot.store,
            writer,
            action="tags.update",
            what="naming tags",
            robot=robot.name,
            origin=origin,
            role=Role.ADMIN,
            requested={"how": "csv"},
        )
        await robot.store.add_audit(
            AuditEntry(
                user,
                writer.client,
                "tags.update",
                [],
                None,
                {"how": "csv"},
                "invalid",
                error.reason,
                robot=robot.name,
                origin=origin,
            )
        )
        raise ApiError(422, error.reason, field=error.field) from None
    return await _replace(robot, writer, request, tags, "csv")

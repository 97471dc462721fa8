"""Layer: service. Output presets per robot (``service.commissioning.presets``): list, save (by
hand or from the command image being sent), delete, export and import (CSV or JSON), what one
would change, and apply: ONE write of all its values through the write pipeline (control
needed, all or nothing, confirmed by the robot, audited as any write with this route as its
origin). Reading is open to whoever may view; saving needs an operator (``preset.*`` audit
rows)."""

from __future__ import annotations

from typing import Annotated, Final

from fastapi import APIRouter, Path, Request, Response

from cobot_hmi.service.api.deps import RobotDep, ViewerDep, WriterDep
from cobot_hmi.service.api.downloads import download
from cobot_hmi.service.api.openapi_extras import WRITE, errors
from cobot_hmi.service.api.origin import audited_action, request_origin
from cobot_hmi.service.api.routes.read import OrjsonResponse
from cobot_hmi.service.commissioning import models
from cobot_hmi.service.commissioning.audit import AuditedAction
from cobot_hmi.service.commissioning.presets import (
    ALL_OUTPUTS_OFF,
    Preset,
    PresetBook,
    PresetError,
    changes,
    checked,
    from_csv,
    from_image,
    to_csv,
)
from cobot_hmi.service.robots.robot import RobotRuntime
from cobot_hmi.service.writes.pipeline import submit_write

router = APIRouter(prefix="/api/v1", tags=["presets"])

_READ: Final = errors(401, 404)
_CHANGE: Final = errors(401, 403, 404, 409, 413, 415, 422, 429, 503)
PresetName = Annotated[str, Path(description="the preset's name", max_length=64)]


def _book(robot: RobotRuntime) -> PresetBook:
    return PresetBook(robot.name, robot.store)


async def _list(robot: RobotRuntime) -> dict[str, object]:
    return {"robot": robot.name, "items": [p.answer() for p in await _book(robot).all()]}


@router.get(
    "/robots/{name}/presets",
    summary='The robot\'s output presets ("All outputs off" first): the JSON export',
    response_model=models.PresetList,
    responses=_READ,
)
async def list_presets(robot: RobotDep, _: ViewerDep) -> OrjsonResponse:
    return OrjsonResponse(await _list(robot))


@router.get(
    "/robots/{name}/presets.csv",
    summary="The robot's presets as CSV: preset,key,label,value (bits 0/1)",
    response_class=Response,
    responses={
        200: {
            "description": "CSV with a header row",
            "content": {"text/csv": {"schema": {"type": "string"}}},
        },
        **_READ,
    },
)
async def presets_csv(robot: RobotDep, _: ViewerDep) -> Response:
    return download(to_csv(await _book(robot).all()), f"{robot.name}-presets.csv")


async def _save(
    action: AuditedAction, robot: RobotRuntime, presets: list[Preset], how: str
) -> None:
    user = action.writer.user
    assert user is not None  # authorized
    book = _book(robot)
    for preset in presets:
        await book.save(preset, user)
    await action.audit(
        "saved",
        fields=sorted({k for p in presets for k in p.items}),
        requested={"how": how, "presets": {p.name: p.items for p in presets}},
        summary=f"presets saved ({how}): " + ", ".join(repr(p.name) for p in presets),
    )


def _preset(body: models.PresetCreate, robot: RobotRuntime) -> Preset:
    image = robot.link.command
    if body.from_image:
        return from_image(body.name, image, body.fields)
    if body.items is None:
        raise PresetError(422, "give items, or from_image: true", "items")
    return checked(body.name, body.items, image)


@router.post(
    "/robots/{name}/presets",
    summary="Save a preset (by hand, or from the command image being sent); replaces one of "
    "the same name",
    response_model=models.Preset,
    responses=_CHANGE,
)
async def save_preset(
    robot: RobotDep, body: models.PresetCreate, writer: WriterDep, request: Request
) -> OrjsonResponse:
    action = audited_action(robot, writer, request, "preset.save")
    requested = body.model_dump(exclude_none=True)
    await action.authorize("saving a preset", requested)
    try:
        preset = _preset(body, robot)
    except PresetError as error:
        raise await action.refused(error, requested=requested) from None
    await _save(action, robot, [preset], "from the image" if body.from_image else "items")
    return OrjsonResponse((await _book(robot).get(preset.name)).answer())


def _imported(body: models.PresetImport, robot: RobotRuntime) -> list[Preset]:
    """Every preset of the import checked (the built-in one, which the exports list, left
    out); ``PresetError`` for the first that is wrong."""
    if body.csv is not None:
        found = from_csv(body.csv)
        return [
            checked(n, items, robot.link.command)
            for n, items in found.items()
            if n != ALL_OUTPUTS_OFF
        ]
    if body.items is not None:
        return [_preset(item, robot) for item in body.items if item.name != ALL_OUTPUTS_OFF]
    raise PresetError(422, "give csv or items", "csv")


@router.post(
    "/robots/{name}/presets/import",
    summary="Import presets (the CSV or the JSON export): all checked first, then each "
    "replaces one of its name",
    response_model=models.PresetList,
    responses=_CHANGE,
)
async def import_presets(
    robot: RobotDep, body: models.PresetImport, writer: WriterDep, request: Request
) -> OrjsonResponse:
    action = audited_action(robot, writer, request, "preset.save")
    await action.authorize("importing presets")
    try:
        presets = _imported(body, robot)
    except PresetError as error:
        raise await action.refused(error, requested={"how": "import"}) from None
    await _save(action, robot, presets, "import")
    return OrjsonResponse(await _list(robot))


@router.delete(
    "/robots/{name}/presets/{preset}",
    summary="Delete a preset (not the built-in one)",
    response_model=models.PresetList,
    responses=_CHANGE,
)
async def delete_preset(
    robot: RobotDep, preset: PresetName, writer: WriterDep, request: Request
) -> OrjsonResponse:
    action = audited_action(robot, writer, request, "preset.delete")
    requested = {"preset": preset}
    await action.authorize("deleting a preset", requested)
    try:
        await _book(robot).delete(preset)
    except PresetError as error:
        raise await action.refused(error, requested=requested) from None
    await action.audit("deleted", requested=requested, summary=f"preset {preset!r} deleted")
    return OrjsonResponse(await _list(robot))


@router.get(
    "/robots/{name}/presets/{preset}/changes",
    summary="What applying the preset would change in the command image being sent now (the "
    "confirmation's list)",
    response_model=models.PresetChanges,
    responses=_READ,
)
async def preset_changes(robot: RobotDep, preset: PresetName, _: ViewerDep) -> OrjsonResponse:
    found = await _book(robot).get(preset)
    return OrjsonResponse({"preset": found.name, "changes": changes(found, robot.link.command)})


@router.post(
    "/robots/{name}/presets/{preset}/apply",
    summary="Apply a preset: ONE write of all its values through the write pipeline (all or "
    "nothing), answered once the robot confirmed it",
    response_model=models.PresetChanges,
    responses=errors(*WRITE),
)
async def apply_preset(
    robot: RobotDep, preset: PresetName, writer: WriterDep, request: Request
) -> OrjsonResponse:
    found = await _book(robot).get(preset)
    before = changes(found, robot.link.command)
    outcome = await submit_write(robot, writer, found.body(), origin=request_origin(request))
    if not outcome.ok:
        raise outcome.error()
    return OrjsonResponse({"preset": found.name, "changes": before, "seq": outcome.seq})

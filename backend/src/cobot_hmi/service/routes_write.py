"""Layer: service. Writing: ``PATCH /api/v1/command`` and control take / release."""

from __future__ import annotations

from typing import Final

from fastapi import APIRouter, Request

from cobot_hmi.layout import O2T_ASSEMBLY
from cobot_hmi.service.deps import OperatorDep, ServiceDep, SessionDep, client_address

router = APIRouter(prefix="/api/v1", tags=["write"])

# The body is read by hand (FastAPI's own validation would answer 422 in another shape before
# the write is audited); this schema documents it for /docs, derived from the layout.
_PATCH_SCHEMA: Final = {
    "type": "object",
    "additionalProperties": False,
    "properties": {
        f.name: {
            "description": f"{f.description}: a map from index (0–{f.count - 1}) to value",
            "type": "object",
            "additionalProperties": {
                "type": {"bool": "boolean", "int": "integer", "float": "number"}[f.value_kind]
            },
        }
        for f in O2T_ASSEMBLY.fields
    },
    "example": {
        "controlbox_do": {"3": True},
        "tool_do": {"1": False},
        "analog_output": {"0": 12.5},
        "analog_output_type": {"0": 0},
        "bit_input_registers": {"40": True},
    },
}


@router.patch(
    "/command",
    summary="Write part of the O→T image; answers once the robot confirms it",
    openapi_extra={
        "requestBody": {
            "required": True,
            "content": {"application/json": {"schema": _PATCH_SCHEMA}},
        }
    },
)
async def patch_command(
    request: Request, service: ServiceDep, session: SessionDep
) -> dict[str, object]:
    raw = await request.body()
    return await service.commander.write(session, client_address(request), raw)


@router.post("/control/take", summary="Take control: O→T to run, bumpless")
async def take_control(
    request: Request, service: ServiceDep, session: OperatorDep
) -> dict[str, object]:
    return await service.control.take(session, client_address(request))


@router.post("/control/release", summary="Release control: O→T back to idle")
async def release_control(
    request: Request, service: ServiceDep, session: OperatorDep
) -> dict[str, object]:
    return await service.control.release(session, client_address(request))

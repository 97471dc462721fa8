"""Layer: service. The API's contract: Tag names of a robot's I/O points and bit registers."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field

from cobot_hmi.service.api.models.frames import _STRICT

# --------------------------------------------------------------------------- tag names


class TagPoint(BaseModel):
    """A taggable point of one robot: I/O or a bit register."""

    key: str = Field(description="``name.index``, 0-based as the frame's arrays: controlbox_do.2")
    label: str = Field(description="the spec's label: DO 3")
    field: str
    index: int = Field(ge=0)
    directions: list[Literal["T2O", "O2T"]]
    name: str | None = Field(description="its tag name (null: none)")


class TagList(BaseModel):
    """``GET /api/v1/robots/{name}/tags``: every taggable point with its name."""

    robot: str
    points: list[TagPoint]
    tags: dict[str, str] = Field(description="``{key: name}`` of the named points only")


class TagUpdate(BaseModel):
    """``PUT /api/v1/robots/{name}/tags``: the whole set of names (a point left out has none)."""

    model_config = _STRICT

    tags: dict[str, str] = Field(
        description='``{"controlbox_do.2": "gripper close"}`` (index 2 is DO 3); an empty name '
        "removes one",
        examples=[{"controlbox_do.2": "gripper close", "bit_input_registers.40": "part ready"}],
    )


class TagImport(BaseModel):
    """``POST /api/v1/robots/{name}/tags/import``: CSV text (``key,label,name``, as the export),
    sent as JSON; replaces every name."""

    model_config = _STRICT

    csv: str = Field(max_length=200_000)

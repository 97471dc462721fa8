"""Layer: service. The API's contract: The layout document (GET /api/v1/layout)."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel

# --------------------------------------------------------------------------- layout document


class FlagDoc(BaseModel):
    abbreviation: str
    full_name: str


class LayoutFieldDoc(BaseModel):
    name: str
    offset: int
    cip_type: Literal["BOOL", "USINT", "REAL"]
    count: int
    first_bit: int | None
    bit_count: int
    scalar: bool
    value_kind: Literal["bool", "int", "float"]
    unit: str
    group: str
    description: str
    channels: list[str]
    value_names: list[str] | None = None
    element_names: list[str] | None = None
    flag: FlagDoc | None = None
    enum: str | None = None


class AssemblyDoc(BaseModel):
    name: str
    direction: Literal["T2O", "O2T"]
    size_bytes: int
    default_instance: int
    description: str
    fields: list[LayoutFieldDoc]


class RobotStateDoc(BaseModel):
    value: int
    name: str
    label: str
    description: str
    pendant_colours: list[str]
    colour_from_table: bool


class RangeDoc(BaseModel):
    low: float
    high: float
    unit: str


class LayoutDocument(BaseModel):
    """``GET /api/v1/layout``: the I/O layout every other shape derives from."""

    layout_version: int
    assemblies: list[AssemblyDoc]
    robot_states: list[RobotStateDoc]
    unknown_state_name: str
    analog_output_ranges: dict[str, RangeDoc]

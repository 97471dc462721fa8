"""Layer: service. The API's contract for the commissioning tools (checkouts and presets): the
Pydantic models of their answers and request bodies, in ``/openapi.json`` like every route's
(``make codegen`` writes the frontend's types from it). Imports pydantic only."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

_STRICT = ConfigDict(extra="forbid")

CheckoutResult = Literal["untested", "seen", "pass", "fail"]
PresetValue = bool | int | float


class CheckoutSample(BaseModel):
    time: float = Field(description="the frame's receive time, s since the epoch")
    value: float = Field(description="the analog input's value then (mA or V per its type)")
    by: str = Field(description="who captured it")


class CheckoutSwitchRecord(BaseModel):
    """One switch of an output from the checkout, as the robot confirmed it."""

    time: float = Field(
        description="when the service had the robot's confirmation, s since the epoch"
    )
    value: PresetValue = Field(description="the value switched to (a bit, or an AO's number)")
    by: str = Field(description="who switched it")
    latency_ms: float | None = Field(description="from the write to the robot's confirmation")
    seq: int | None = Field(
        default=None, description="the number of the robot's frame that showed it (null: not kept)"
    )


class CheckoutPoint(BaseModel):
    """One point of a checkout and what became of it."""

    key: str = Field(description="``field.index``, 0-based: controlbox_di.4 is DI 5")
    label: str = Field(description='as the robot prints it: "DI 5", "Tool DO 2", "Register in 12"')
    tag: str | None = Field(description="its tag name (null: none)")
    kind: Literal["input", "output"] = Field(
        description="input: seen in the robot's frames; output: switched from the checkout"
    )
    signal: Literal["digital", "analog"]
    result: CheckoutResult
    seen_at: float | None = Field(description="digital input: the frame showing the first edge")
    seen_before: bool | None = Field(description="the value before that edge")
    seen_after: bool | None = Field(description="the value after it")
    samples: list[CheckoutSample] = Field(description="analog input: the captured values")
    switched_at: float | None = Field(description="output: when the robot confirmed it last")
    switched_value: PresetValue | None
    switched_by: str | None
    switches: list[CheckoutSwitchRecord] = Field(
        description="output: every switch the robot confirmed, oldest first (the evidence of a "
        "pass: on confirmed, then off confirmed)"
    )
    recorded_at: float | None = Field(description="when the checker recorded pass or fail")
    recorded_by: str | None
    comment: str | None


class CheckoutCounts(BaseModel):
    untested: int = Field(ge=0)
    seen: int = Field(ge=0)
    pass_: int = Field(ge=0, alias="pass")
    fail: int = Field(ge=0)


class CheckoutSummary(BaseModel):
    """A checkout without its points."""

    id: int
    robot: str
    started_at: float
    started_by: str
    closed_at: float | None = Field(description="null: open; closed: read-only")
    closed_by: str | None
    identity: dict[str, str | int] | None = Field(
        description="the robot's CIP identity when the checkout started (null: not read)"
    )
    counts: CheckoutCounts


class Checkout(CheckoutSummary):
    """``GET /api/v1/robots/{name}/checkouts/{id}``: every point of the layout."""

    points: list[CheckoutPoint]


class CheckoutList(BaseModel):
    items: list[CheckoutSummary] = Field(description="newest first")


class CheckoutVerdict(BaseModel):
    """The checker's result of one point."""

    model_config = _STRICT

    result: Literal["pass", "fail"]
    comment: str = Field(
        default="", max_length=500, description="what was checked; a fail needs one (422 without)"
    )


class CheckoutSwitch(BaseModel):
    """An output switched from the checkout (one write through the write pipeline)."""

    model_config = _STRICT

    value: PresetValue = Field(description="a bit (DO, Tool DO, Register in) or a number (AO)")


class Preset(BaseModel):
    name: str
    items: dict[str, PresetValue] = Field(
        description='``{"field.index": value}`` over the O→T image: {"bit_input_registers.0": true}'
    )
    labels: dict[str, str] = Field(description="the label of each item's key")
    created_at: float | None
    created_by: str | None
    builtin: bool = Field(description='"All outputs off": every robot has it, unchangeable')


class PresetList(BaseModel):
    robot: str
    items: list[Preset]


class PresetCreate(BaseModel):
    """A preset made by hand (``items``) or from the command image being sent (``from_image``,
    all of it or the ``fields`` named); a preset of the same name is replaced."""

    model_config = _STRICT

    name: str = Field(min_length=1, max_length=64)
    items: dict[str, PresetValue] | None = None
    from_image: bool = False
    fields: list[str] | None = Field(
        default=None, description="with from_image: only these O→T fields (bit_input_registers)"
    )


class PresetImport(BaseModel):
    """Presets imported (each replaces one of its name): the CSV export's text, or the JSON
    export's ``items``."""

    model_config = _STRICT

    csv: str | None = Field(default=None, max_length=500_000)
    items: list[PresetCreate] | None = None


class PresetChange(BaseModel):
    key: str
    label: str
    from_: PresetValue = Field(alias="from")
    to: PresetValue


class PresetChanges(BaseModel):
    """What applying a preset changes in the command image being sent now."""

    preset: str
    changes: list[PresetChange]
    seq: int | None = Field(
        default=None,
        description="apply: the stream's number of the frame that confirmed the write (a page "
        "shows that frame as soon as it has it); null: what applying would change, or no frame "
        "confirms it",
    )

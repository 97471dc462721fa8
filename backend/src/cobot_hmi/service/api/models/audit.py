"""Layer: service. The API's contract: The audit trail's rows and pages."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field

from cobot_hmi.service.api.models.frames import ElementValue, Json

# --------------------------------------------------------------------------- audit

AuditAction = Literal[
    "write",
    "control.take",
    "control.release",
    "alarm.ack",
    "alarm.shelve",
    "alarm.unshelve",
    "tags.update",
    "checkout.start",
    "checkout.result",
    "checkout.capture",
    "checkout.close",
    "preset.save",
    "preset.delete",
    "health.baseline",
]
AuditOutcome = Literal[
    "confirmed",
    "timeout",
    "invalid",
    "refused",
    "unauthorized",
    "forbidden",
    "granted",
    "released",
    "pending",
    "acknowledged",
    "shelved",
    "unshelved",
    "updated",
    "unchanged",
    "started",
    "recorded",
    "captured",
    "closed",
    "saved",
    "deleted",
]


class AuditRow(BaseModel):
    """One write attempt or control change."""

    id: int
    time: float
    robot: str | None = Field(
        description="the robot's name (null: rows from before robots had names)"
    )
    user: str | None
    client: str | None = Field(description="the writer's address or client id")
    origin: str | None = Field(description="which door the request came through (HTTP route, …)")
    action: AuditAction
    fields: list[str] = Field(description="``name.index`` keys of the elements touched")
    before: dict[str, ElementValue] | None
    requested: Json = Field(description="the requested values (a malformed body: what came)")
    outcome: AuditOutcome
    reason: str | None
    summary: str | None = Field(
        default=None,
        description="what was asked in words with the spec's labels: "
        '"DO 3 (gripper close) = on", "AO 1 type = voltage, AO 1 = 5 V"',
    )
    labels: dict[str, str] = Field(
        default_factory=dict,
        description="the spec's label of each key of ``fields`` (controlbox_do.2 → DO 3)",
    )
    tags: dict[str, str] | None = Field(
        default=None, description="tag names of the touched points when the row was written"
    )
    seal_seq: int | None = Field(
        default=None,
        description="the row's place in the audit trail's hash chain, sealed when it became "
        "final (null: pending, sealed with its outcome)",
    )
    seal_hash: str | None = Field(
        default=None,
        description="SHA-256 (hex) over the row and the previous seal: ``cobot-hmi audit "
        "verify`` (docs/operations.md, Audit verify)",
    )


class AuditPage(BaseModel):
    items: list[AuditRow]
    total: int = Field(ge=0)

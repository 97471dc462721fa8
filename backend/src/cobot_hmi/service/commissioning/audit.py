"""Layer: service. Every commissioning action in the audit trail, as tags and alarms are: who,
from where, which points, what was asked, the outcome (a refusal with its reason)."""

from __future__ import annotations

from cobot_hmi.service.storage.store import AuditEntry, Store
from cobot_hmi.service.writes.pipeline import Writer


async def audit_action(
    store: Store,
    writer: Writer,
    *,
    robot: str,
    action: str,
    origin: str,
    outcome: str,
    fields: list[str] | None = None,
    requested: object = None,
    reason: str | None = None,
    summary: str | None = None,
) -> None:
    """One row, committed durably (on a full disk it waits in memory: ``Store.keep_audit``)."""
    await store.keep_audit(
        AuditEntry(
            writer.user,
            writer.client,
            action,
            fields or [],
            None,
            requested,
            outcome,
            reason,
            robot=robot,
            origin=origin,
            summary=summary,
        ),
        happened=True,
    )

"""Layer: service. Every commissioning action in the audit trail, as tags and alarms are: who,
from where, which points, what was asked, the outcome (a refusal with its reason).

``AuditedAction`` is one request's action (``checkout.result``, ``preset.save`` …): authorize
the writer (a refusal audited, 401 / 403), then either the outcome's row or a refusal's row
and the ``ApiError`` to answer with."""

from __future__ import annotations

from dataclasses import dataclass

from cobot_hmi.service.errors import ApiError
from cobot_hmi.service.storage.store import AuditEntry, Store
from cobot_hmi.service.writes.pipeline import Writer, authorize_audited


@dataclass(frozen=True, slots=True)
class AuditedAction:
    store: Store
    writer: Writer
    robot: str
    action: str
    origin: str
    """The door: ``POST /api/v1/robots/left/checkouts``."""

    async def authorize(self, what: str, requested: object = None) -> str:
        """The writer's user name; ``ApiError`` 401 / 403, audited."""
        return await authorize_audited(
            self.store,
            self.writer,
            action=self.action,
            what=what,
            robot=self.robot,
            origin=self.origin,
            requested=requested,
        )

    async def audit(
        self,
        outcome: str,
        *,
        fields: list[str] | None = None,
        requested: object = None,
        reason: str | None = None,
        summary: str | None = None,
    ) -> None:
        """One row, committed durably (on a full disk it waits in memory: ``keep_audit``)."""
        await self.store.keep_audit(
            AuditEntry(
                self.writer.user,
                self.writer.client,
                self.action,
                fields or [],
                None,
                requested,
                outcome,
                reason,
                robot=self.robot,
                origin=self.origin,
                summary=summary,
            ),
            happened=True,
        )

    async def refused(
        self, error: ApiError, fields: list[str] | None = None, requested: object = None
    ) -> ApiError:
        """The refusal audited (``refused``, or ``invalid`` for a 422); the error to raise."""
        outcome = "invalid" if error.status == 422 else "refused"
        await self.audit(outcome, fields=fields, requested=requested, reason=error.reason)
        return error

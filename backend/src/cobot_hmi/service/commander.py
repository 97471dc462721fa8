"""Layer: service. A write to the robot's outputs, from request to confirmation, audited.

Order: who (401/403) → what (422, nothing applied) → whether (409: connection, mode,
control) → an audit row ``pending`` committed to disk → the new O→T image → confirmation →
the row's outcome committed → the answer. A crash at any point leaves the attempt on disk.

Confirmation: outputs the robot echoes (DO, tool DO, AO type, AO) are confirmed by the first
T→O frame after the change that shows them; bit input registers, which the robot does not
echo as such, once the O→T packet carrying them has gone out.
"""

from __future__ import annotations

import time
from collections import Counter
from typing import Final

import orjson

from cobot_hmi.codec import command_to_json
from cobot_hmi.scanner.originator import NotConnectedError, ReadOnlyError
from cobot_hmi.service.auth import Session
from cobot_hmi.service.control import Control
from cobot_hmi.service.errors import ApiError, conflict, forbidden, unauthorized
from cobot_hmi.service.hub import Hub
from cobot_hmi.service.link import RobotLink
from cobot_hmi.service.store import AuditEntry, Store
from cobot_hmi.service.users import Role
from cobot_hmi.service.writes import WriteValidationError, frame_shows, plan_write, robot_reports

ACTION: Final = "write"
MAX_BODY_BYTES: Final = 64 * 1024


class Commander:
    """Executes ``PATCH /api/v1/command``; counts outcomes for /metrics."""

    def __init__(
        self, link: RobotLink, store: Store, hub: Hub, control: Control, *, timeout_s: float
    ) -> None:
        self._link = link
        self._store = store
        self._hub = hub
        self._control = control
        self.timeout_s = timeout_s
        self.outcomes: Counter[str] = Counter()

    async def write(
        self, session: Session | None, client: str | None, raw_body: bytes
    ) -> dict[str, object]:
        """The ``PATCH`` answer for ``raw_body`` (JSON); ``ApiError`` for every refusal."""
        started = time.perf_counter()
        user = session.user.name if session is not None else None
        body: object = None
        try:
            if session is None:
                raise unauthorized("login required to write")
            if session.user.role < Role.OPERATOR:
                raise forbidden(f"writing needs the operator role; {user} is a viewer")
            body = _parse(raw_body)
            async with self._control.lock:
                return await self._write_locked(session, client, body, started)
        except ApiError as error:
            if error.status != 504:  # a timeout was audited with its row already
                outcome = {401: "unauthorized", 403: "forbidden", 422: "invalid"}.get(
                    error.status, "refused"
                )
                self.outcomes[outcome] += 1
                fields = _body_fields(body)
                await self._store.add_audit(
                    AuditEntry(
                        user,
                        client,
                        ACTION,
                        fields,
                        None,
                        body,
                        outcome,
                        error.reason,
                        robot=self._link.name,
                    )
                )
            raise

    async def _write_locked(
        self, session: Session, client: str | None, body: object, started: float
    ) -> dict[str, object]:
        before_image = self._link.command
        try:
            plan = plan_write(body, before_image)
        except WriteValidationError as error:
            raise ApiError(422, error.reason, field=error.field) from None
        refusal = self._control.refusal_to_write()
        if refusal is None and not self._control.holds(session):
            holder = self._control.holder
            refusal = (
                "take control first (POST /api/v1/control/take)"
                if holder is None
                else f"control is held by {holder.user}"
            )
        if refusal is not None:
            raise conflict(refusal)

        row_id = await self._store.add_audit(
            AuditEntry(
                session.user.name,
                client,
                ACTION,
                plan.field_names,
                plan.values(before_image),
                plan.values(plan.image),
                "pending",
                None,
                robot=self._link.name,
            ),
            fsync=False,  # the outcome's fsync below covers it (see ``store``)
        )
        after_seq = self._hub.seq
        try:
            packets_out = await self._link.set_command(plan.image)
        except (NotConnectedError, ReadOnlyError) as error:
            await self._finish(row_id, session, plan.field_names, "refused", str(error))
            raise conflict(str(error)) from None

        deadline = started + self.timeout_s
        confirmed = True
        frame = None
        if plan.by_frame:
            item = await self._hub.wait_for_frame(
                lambda f: frame_shows(f, plan.image, plan.by_frame),
                after_seq,
                max(0.0, deadline - time.perf_counter()),
            )
            confirmed = item is not None
        if confirmed and plan.by_packet:
            confirmed = await self._link.wait_sent(
                packets_out, max(0.0, deadline - time.perf_counter())
            )
        latency_ms = (time.perf_counter() - started) * 1000
        if not confirmed:
            latest = self._hub.latest
            frame = latest[2] if latest is not None else None
            reports = robot_reports(frame, plan.by_frame)
            if plan.by_frame:
                reason = (
                    f"the robot did not show the new outputs within {self.timeout_s * 1000:.0f} ms"
                )
            else:
                reason = (
                    "the O→T packet with the bit input registers did not go out within "
                    f"{self.timeout_s * 1000:.0f} ms"
                )
            await self._finish(row_id, session, plan.field_names, "timeout", reason)
            raise ApiError(504, reason, robot_reports=reports)
        await self._finish(row_id, session, plan.field_names, "confirmed", None)
        return {
            "outcome": "confirmed",
            "image": command_to_json(plan.image),
            "latency_ms": round(latency_ms, 3),
        }

    async def _finish(
        self, row_id: int, session: Session, fields: list[str], outcome: str, reason: str | None
    ) -> None:
        self.outcomes[outcome] += 1
        await self._store.finish_audit(row_id, outcome, reason)
        self._hub.publish_event(
            {
                "kind": "write",
                "time": time.time(),
                "user": session.user.name,
                "fields": fields,
                "outcome": outcome,
                "reason": reason,
            }
        )


def _parse(raw_body: bytes) -> object:
    if len(raw_body) > MAX_BODY_BYTES:
        raise ApiError(422, f"the body is larger than {MAX_BODY_BYTES} bytes", field=None)
    try:
        return orjson.loads(raw_body)
    except orjson.JSONDecodeError as error:
        raise ApiError(422, f"the body is not JSON: {error}", field=None) from None


def _body_fields(body: object) -> list[str]:
    if not isinstance(body, dict):
        return []
    fields: list[str] = []
    for name, value in body.items():
        if isinstance(value, dict):
            fields.extend(f"{name}.{key}" for key in value)
        else:
            fields.append(str(name))
    return fields

"""Layer: service (Sparkplug). Commands from host applications: NCMD rebirth, DCMD writes.

An NCMD ``Node Control/Rebirth`` may carry ``Node Control/Alarm History Since`` (DateTime, ms
since the epoch): the host lost messages and asks, beside the births, for every alarm
transition since then again (as historical, after each DBIRTH; our plant does this).

A DCMD names metrics (by name or alias) of one robot: ``command/<field>/<channel>`` elements
become one write body (``{field: {index: value}}``, as ``PATCH …/command`` takes it) that goes
through the service's one write pipeline (``service.writes.pipeline.submit_write``): validated
whole, refused unless the MQTT writer holds control, audited with the writer's MQTT identity,
confirmed by the robot's own frame. ``Control/Take`` and ``Control/Release`` (true) take and
release control through the same pipeline. With MQTT writes off every DCMD is refused (and
audited). The outcome goes back as the device's ``Write/Outcome`` and ``Write/Reason``: a
refusal's reason (the audit trail that cannot be written on a full disk included: ``refused``,
nothing applied), and for a write confirmed while its audit row waits for room on the disk,
that warning.

Imports the write pipeline, the store and ``catalogue``/``payload``; never a route.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Final

from cobot_hmi.service.errors import ApiError
from cobot_hmi.service.storage.store import AuditEntry
from cobot_hmi.service.writes.pipeline import (
    AUDIT_PENDING_WARNING,
    Writer,
    WriteTarget,
    release_control,
    submit_write,
    take_control,
)
from cobot_hmi.sparkplug.catalogue import ALARM_HISTORY_SINCE, REBIRTH, Catalogue, MetricDef, Role
from cobot_hmi.sparkplug.payload import Payload, metric_value

log = logging.getLogger(__name__)

WRITES_OFF: Final = "writes over MQTT are off (start the service with --mqtt-writes)"


@dataclass(slots=True)
class DeviceCommand:
    """What one DCMD asks."""

    body: dict[str, dict[str, object]] = field(default_factory=dict)
    take: bool = False
    release: bool = False
    problems: list[str] = field(default_factory=list)
    """Metrics that are not writable or carry no value."""

    @property
    def empty(self) -> bool:
        return not (self.body or self.take or self.release or self.problems)


@dataclass(frozen=True, slots=True)
class CommandOutcome:
    outcome: str
    reason: str


def wants_rebirth(payload: Payload) -> bool:
    """An NCMD whose ``Node Control/Rebirth`` metric is true."""
    return any(m.name == REBIRTH and metric_value(m) is True for m in payload.metrics)


def alarm_history_since(payload: Payload) -> int | None:
    """An NCMD's ``Node Control/Alarm History Since`` (ms), if it has one."""
    for metric in payload.metrics:
        if metric.name == ALARM_HISTORY_SINCE:
            value = metric_value(metric)
            if isinstance(value, int) and not isinstance(value, bool):
                return value
    return None


def parse_device_command(payload: Payload, catalogue: Catalogue, alias_base: int) -> DeviceCommand:
    """The DCMD's metrics as a write body and control actions (``problems`` for the rest)."""
    command = DeviceCommand()
    for metric in payload.metrics:
        definition: MetricDef | None = None
        if metric.name:
            definition = catalogue.by_name.get(metric.name)
        elif metric.HasField("alias"):
            offset = metric.alias - alias_base
            if 0 <= offset < len(catalogue.metrics):
                definition = catalogue.metrics[offset]
        label = metric.name or f"alias {metric.alias}"
        if definition is None or not definition.writable:
            command.problems.append(f"{label} is not a writable metric of this robot")
            continue
        value = metric_value(metric)
        if value is None:
            command.problems.append(f"{label} carries no value")
            continue
        if definition is catalogue.control_take:
            command.take = value is True
        elif definition is catalogue.control_release:
            command.release = value is True
        elif definition.role is Role.COMMAND and definition.field is not None:
            command.body.setdefault(definition.field, {})[str(definition.index)] = value
    return command


async def execute(
    robot: WriteTarget,
    writer: Writer,
    command: DeviceCommand,
    *,
    origin: str,
    writes_enabled: bool,
) -> CommandOutcome:
    """Run one DCMD: take control, write, release, in that order; the last step's outcome."""
    if not writes_enabled or command.problems:
        reason = WRITES_OFF if not writes_enabled else "; ".join(command.problems)
        outcome = "refused" if not writes_enabled else "invalid"
        await robot.store.keep_audit(
            AuditEntry(
                writer.user,
                writer.client,
                "write",
                sorted(command.body),
                None,
                {"body": command.body, "take": command.take, "release": command.release},
                outcome,
                reason,
                robot=robot.name,
                origin=origin,
            )
        )
        robot.writes.outcomes[outcome] += 1
        return CommandOutcome(outcome, reason)
    result = CommandOutcome("confirmed", "")
    if command.take:
        try:
            await take_control(robot, writer, origin=origin)
            result = CommandOutcome("granted", "")
        except ApiError as error:
            return CommandOutcome("refused", error.reason)
    if command.body:
        written = await submit_write(robot, writer, command.body, origin=origin)
        warning = AUDIT_PENDING_WARNING if written.audit_pending else ""
        result = CommandOutcome(written.outcome, written.reason or warning)
        if not written.ok:
            return result
    if command.release:
        try:
            await release_control(robot, writer, origin=origin)
            result = CommandOutcome("released", "")
        except ApiError as error:
            return CommandOutcome("refused", error.reason)
    return result

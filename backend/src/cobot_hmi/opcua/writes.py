"""Layer: service (OPC UA). Writes to the command image, and taking and releasing control.

Off unless ``opcua_writes``: then the command variables are read-only (their AccessLevel
says so), a write is ``BadNotWritable`` before it reaches anything (``access_level_refusal``,
as for every variable whose AccessLevel has no CurrentWrite: OPC 10000-4 §5.10.4 keeps
``BadUserAccessDenied`` for a variable this user may not write, which others may), and the
robot's object has no ``TakeControl`` and ``ReleaseControl``: a session that cannot write must
not hold control and lock the panel's operator out. On, the variables of
one robot written in one Write request become one write body (``{field: {index: value}}``, as
``PATCH …/command`` takes it) that goes through the service's one write pipeline: validated
whole, audited with the OPC UA user and the session (``client``: the peer's address and the
session's id), applied, and answered only when the robot's own frame shows it. Each of those
variables gets the outcome's status:

=========================  ===============================================================
pipeline outcome            OPC UA status
=========================  ===============================================================
confirmed (200)             Good
unauthorized, forbidden     BadUserAccessDenied (anonymous, or below the operator role)
refused (409)               BadInvalidState (no control, another holds it, not connected)
invalid (422)               BadTypeMismatch (a value of another type), else BadOutOfRange
timeout (504)               BadTimeout (the robot's frame did not show it in time)
=========================  ===============================================================

``TakeControl`` and ``ReleaseControl`` (methods of the robot's object, with writes on only) go
through the same
pipeline's control steps for the session's own control session; their output is the holder
afterwards. A closed session's control is released (``closed``).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Coroutine, Mapping
from dataclasses import dataclass
from typing import Any, Final

from asyncua import ua
from asyncua.crypto.permission_rules import User
from asyncua.server.address_space import AddressSpace

from cobot_hmi.opcua.auth import OpcUaUser
from cobot_hmi.opcua.bindings import CommandBinding, RobotNodes
from cobot_hmi.opcua.feed import ApiError, ServiceFeed, Writer

log = logging.getLogger(__name__)

ORIGIN_WRITE: Final = "OPC UA Write"
ORIGIN_TAKE: Final = "OPC UA TakeControl"
ORIGIN_RELEASE: Final = "OPC UA ReleaseControl"
_STATUS: Final = {
    200: ua.StatusCodes.Good,
    401: ua.StatusCodes.BadUserAccessDenied,
    403: ua.StatusCodes.BadUserAccessDenied,
    409: ua.StatusCodes.BadInvalidState,
    422: ua.StatusCodes.BadOutOfRange,
    504: ua.StatusCodes.BadTimeout,
}


def access_level_refusal(aspace: AddressSpace, value: ua.WriteValue) -> ua.StatusCode | None:
    """What a write no user may make is answered: ``BadNodeIdUnknown`` or
    ``BadAttributeIdInvalid`` for what does not exist (asyncua would say
    ``BadUserAccessDenied``), ``BadNotWritable`` for an attribute other than the Value (no node
    here has a WriteMask) or a variable whose AccessLevel has no CurrentWrite; ``None`` for a
    writable variable (asyncua's own checks answer it: its UserAccessLevel, its data type)."""
    if value.AttributeId != ua.AttributeIds.Value:
        found = aspace.read_attribute_value(value.NodeId, value.AttributeId).StatusCode
        if found is not None and not found.is_good():
            return found
        return ua.StatusCode(ua.StatusCodes.BadNotWritable)
    level = aspace.read_attribute_value(value.NodeId, ua.AttributeIds.AccessLevel)
    if level.StatusCode is not None and not level.StatusCode.is_good():
        return level.StatusCode  # no such node, or not a variable (no AccessLevel)
    mask = level.Value.Value if level.Value is not None else None
    if isinstance(mask, int) and not mask & ua.AccessLevel.CurrentWrite.mask:
        return ua.StatusCode(ua.StatusCodes.BadNotWritable)
    return None


@dataclass(frozen=True, slots=True)
class Caller:
    """Who sent a request: the session's user, its peer and its id."""

    user: User
    peer: str
    session_id: str

    def writer(self, feed: ServiceFeed) -> Writer:
        client = f"OPC UA {self.peer} session {self.session_id}"
        user = self.user
        if not isinstance(user, OpcUaUser) or user.account is None or user.session is None:
            return Writer(None, None, client)
        account = feed.current(user.account)  # removed or given another role since login
        if account is None or account.role != user.account.role:
            return Writer(None, None, client)
        return Writer(account.name, account.role, client, user.session)


class CommandWrites:
    """Routes writes and method calls of the robots' nodes (see the module docstring)."""

    def __init__(
        self,
        feed: ServiceFeed,
        robots: Mapping[str, RobotNodes],
        *,
        enabled: bool,
        written: Callable[[str], Coroutine[Any, Any, None]],
    ) -> None:
        """``written(robot)``: refresh the robot's command variables after a write."""
        self._feed = feed
        self._enabled = enabled
        self._written = written
        self._commands: dict[ua.NodeId, tuple[str, CommandBinding]] = {}
        self._methods: dict[ua.NodeId, tuple[str, bool]] = {}
        for name, nodes in robots.items():
            if enabled:
                for node, binding in nodes.command_by_node.items():
                    self._commands[node] = (name, binding)
            if enabled and nodes.take_control is not None:
                self._methods[nodes.take_control] = (name, True)
            if enabled and nodes.release_control is not None:
                self._methods[nodes.release_control] = (name, False)
        self.outcomes: dict[str, int] = {}

    def owns_write(self, value: ua.WriteValue) -> bool:
        return value.NodeId in self._commands

    def owns_call(self, request: ua.CallMethodRequest) -> bool:
        return request.MethodId in self._methods

    async def write(self, caller: Caller, values: list[ua.WriteValue]) -> list[ua.StatusCode]:
        """One pipeline write per robot named; each value's status (module docstring)."""
        statuses: list[ua.StatusCode | None] = [None] * len(values)
        bodies: dict[str, dict[str, dict[str, object]]] = {}
        members: dict[str, list[int]] = {}
        mismatched: set[str] = set()
        for position, value in enumerate(values):
            robot, binding = self._commands[value.NodeId]
            if value.AttributeId != ua.AttributeIds.Value or value.IndexRange:
                statuses[position] = ua.StatusCode(ua.StatusCodes.BadWriteNotSupported)
                continue
            variant = value.Value.Value if value.Value is not None else None
            if variant is None or variant.VariantType != binding.variant:
                mismatched.add(robot)
            written = None if variant is None else variant.Value
            key = "0" if binding.index is None else str(binding.index)
            bodies.setdefault(robot, {}).setdefault(binding.field, {})[key] = written
            members.setdefault(robot, []).append(position)
        writer = caller.writer(self._feed)
        for robot, body in bodies.items():
            outcome = await self._feed.write(robot, writer, body, ORIGIN_WRITE)
            self.outcomes[outcome.outcome] = self.outcomes.get(outcome.outcome, 0) + 1
            code = _STATUS.get(outcome.status, ua.StatusCodes.BadInternalError)
            if outcome.status == 422 and robot in mismatched:
                code = ua.StatusCodes.BadTypeMismatch
            if outcome.ok:
                await self._written(robot)
            else:
                log.info("OPC UA write to %s by %s: %s", robot, writer.user, outcome.reason)
            for position in members[robot]:
                statuses[position] = ua.StatusCode(code)
        return [
            s if s is not None else ua.StatusCode(ua.StatusCodes.BadInternalError) for s in statuses
        ]

    async def call(self, caller: Caller, request: ua.CallMethodRequest) -> ua.CallMethodResult:
        robot, take = self._methods[request.MethodId]
        result = ua.CallMethodResult()
        if request.InputArguments:
            result.StatusCode = ua.StatusCode(ua.StatusCodes.BadTooManyArguments)
            return result
        writer = caller.writer(self._feed)
        try:
            if take:
                status = await self._feed.take_control(robot, writer, ORIGIN_TAKE)
            else:
                status = await self._feed.release_control(robot, writer, ORIGIN_RELEASE)
        except ApiError as error:
            result.StatusCode = ua.StatusCode(
                _STATUS.get(error.status, ua.StatusCodes.BadInternalError)
            )
            return result
        holder = status.get("holder")
        user = holder.get("user") if isinstance(holder, dict) else None
        result.StatusCode = ua.StatusCode(ua.StatusCodes.Good)
        result.OutputArguments = [ua.Variant(str(user or ""), ua.VariantType.String)]
        return result

    async def closed(self, user: User) -> None:
        """A session ended: the control its control session held is released."""
        if isinstance(user, OpcUaUser) and user.session is not None:
            await self._feed.drop_control(user.session, "OPC UA session closed")
